#!/usr/bin/env bash
# Start or resume the `laptop` evidence campaign (docs/results.md), whatever the machine still holds.
#
#   bash tools/campaign.sh            # install what is missing, check out the campaign, train
#   bash tools/campaign.sh --dry-run  # the same, but only list the runs each phase would train
#
# Installs torch and this checkout when they are missing, adds each phase's worktree (one fixed
# commit, outside the repository) when it is gone, and starts the queue in the background, unless
# a campaign.py is already training into the same folder: three phases, one after the other, each
# tools/campaign.py run from the worktree of its experiments' commit, so that every experiment
# trains from one commit. Each trains the runs the campaign lacks, two at a time, leaving out
# those data/laptop holds finished, and ships and commits each run into data/laptop the moment
# it finishes.
#
#   phase 1, from CAMPAIGN_COMMIT (9972821) in CAMPAIGN_WORKTREE (~/campaign): the `laptop`
#     budget's runs (`--seeds none`);
#   phase 2, from C5_COMMIT (8d18b17) in CAMPAIGN_C5_WORKTREE (~/campaign-c5): the sensory
#     failure on a mastered module (`--only 'sensor_failure_mastered/*'`), which 9972821 does not
#     know, into the same output folder;
#   phase 3, from CAMPAIGN_COMMIT again: the seeds beyond the budget's (tools/campaign.py's
#     DEFAULT_SEEDS: the distractors' seed 2, then main's seeds 3 and 4).
# Phase 2 comes before phase 3 because C5 has no reading on a mastered module until its runs are
# trained, while C1 and C4 already have theirs at the budget's seeds; the extra seeds sharpen them.
#
# A campaign.py started from an earlier checkout goes on with its own queue until it ends: this
# script starts the new one once it has (or once it is stopped; the runs in flight resume from
# their checkpoints). Settings (environment): CAMPAIGN_COMMIT, CAMPAIGN_WORKTREE,
# CAMPAIGN_C5_COMMIT (overrides C5_COMMIT), CAMPAIGN_C5_WORKTREE, CAMPAIGN_RUNS.
# The background job is `campaign.sh --queue` (phase 1, then `campaign.sh --phase2`, which runs
# phase 2 and then `campaign.sh --phase3`); each later phase is read anew from this file.
set -euo pipefail

# The commit `sensor_failure_mastered` trains from.
C5_COMMIT=8d18b17

main() {
    local commit=${CAMPAIGN_COMMIT:-9972821}
    local worktree=${CAMPAIGN_WORKTREE:-$HOME/campaign}
    local c5_commit=${CAMPAIGN_C5_COMMIT:-$C5_COMMIT}
    local c5_worktree=${CAMPAIGN_C5_WORKTREE:-$HOME/campaign-c5}
    local runs=${CAMPAIGN_RUNS:-$HOME/curious-runs}
    local mode=${1:-}
    repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
    queue=(python "$repo/tools/campaign.py" --out "$runs/laptop" --shipped "$repo/data/laptop"
           --ship --set torch_threads=1)
    phase1=(--seeds none)
    phase2=(--only 'sensor_failure_mastered/*')

    case "$mode" in
        "" | --dry-run | --queue | --phase2 | --phase3) ;;
        *) echo "campaign.sh: unknown option $mode (--dry-run)" >&2; return 2 ;;
    esac
    python -c "import torch" 2>/dev/null || python -m pip install -q torch==2.13.0
    # from /, so that the checkout itself on the path does not pass for an installed curious
    (cd / && python -c "import curious, dagster, pytest" 2>/dev/null) ||
        python -m pip install -q -e "$repo[test]"

    case "$mode" in
        --dry-run)
            checkout "$worktree" "$commit"
            checkout "$c5_worktree" "$c5_commit"
            echo "phase 1, the budget's runs, from ${commit} in $worktree:"
            in_worktree "$worktree" "${queue[@]}" "${phase1[@]}" --dry-run
            echo "phase 2, once phase 1 ends, from ${c5_commit} in $c5_worktree:"
            in_worktree "$c5_worktree" "${queue[@]}" "${phase2[@]}" --dry-run
            echo "phase 3, once phase 2 ends, the seeds beyond the budget's, from ${commit}" \
                 "in $worktree (with the runs phase 1 has not finished):"
            in_worktree "$worktree" "${queue[@]}" --dry-run
            ;;
        --queue)
            checkout "$worktree" "$commit"
            echo "campaign.sh: phase 1 from ${commit} in $worktree, $(date -u '+%F %T UTC')"
            in_worktree "$worktree" "${queue[@]}" "${phase1[@]}"
            # read anew, so that an edit made while phase 1 trained is the one phase 2 uses
            exec bash "$repo/tools/campaign.sh" --phase2
            ;;
        --phase2)
            refuse_if_training "$runs"
            checkout "$c5_worktree" "$c5_commit"
            echo "campaign.sh: phase 2 from ${c5_commit} in $c5_worktree, $(date -u '+%F %T UTC')"
            in_worktree "$c5_worktree" "${queue[@]}" "${phase2[@]}"
            exec bash "$repo/tools/campaign.sh" --phase3
            ;;
        --phase3)
            refuse_if_training "$runs"
            checkout "$worktree" "$commit"
            echo "campaign.sh: phase 3 from ${commit} in $worktree, $(date -u '+%F %T UTC')"
            in_worktree "$worktree" "${queue[@]}"
            ;;
        "")
            checkout "$worktree" "$commit"
            checkout "$c5_worktree" "$c5_commit"
            if pgrep -f "tools/campaign.py --out $runs/laptop" >/dev/null; then
                echo "campaign.sh: the campaign is already training (pgrep -af tools/campaign.py)"
                return 0
            fi
            mkdir -p "$runs"
            nohup nice -n 5 bash "$repo/tools/campaign.sh" --queue >>"$runs/laptop-main.log" 2>&1 &
            echo "campaign.sh: training (pid $!) phase 1 from ${commit} in $worktree, then" \
                 "phase 2 from ${c5_commit} in $c5_worktree, then phase 3 from ${commit};" \
                 "runs in $runs/laptop, log $runs/laptop-main.log"
            ;;
    esac
}

# checkout DIR COMMIT: add the worktree DIR at COMMIT when it is gone; refuse one elsewhere or
# with local changes.
checkout() {
    local dir=$1 commit=$2 head
    if [ ! -d "$dir" ]; then
        git -C "$repo" worktree prune
        git -C "$repo" worktree add --detach "$dir" "$commit"
    fi
    head=$(git -C "$dir" rev-parse HEAD)
    if [ "$head" != "$(git -C "$repo" rev-parse "$commit^{commit}")" ]; then
        echo "campaign.sh: $dir is at ${head:0:7}, not the campaign's $commit: move it away" >&2
        exit 2
    fi
    if [ -n "$(git -C "$dir" status --porcelain --untracked-files=no)" ]; then
        echo "campaign.sh: $dir has local changes: the campaign trains from $commit as it is" >&2
        exit 2
    fi
}

# in_worktree DIR COMMAND...: COMMAND in DIR, importing curious and pipelines from there.
in_worktree() {
    local dir=$1
    shift
    (cd "$dir" && PYTHONPATH=$dir MUJOCO_GL=disable "$@")
}

# refuse_if_training RUNS: stop where a campaign.py already trains into RUNS/laptop.
refuse_if_training() {
    if pgrep -f "tools/campaign.py --out $1/laptop" >/dev/null; then
        echo "campaign.sh: the campaign is already training (pgrep -af tools/campaign.py)" >&2
        exit 2
    fi
}

# one line, read whole before it runs: the file may be edited while it trains
main "$@"; exit $?
