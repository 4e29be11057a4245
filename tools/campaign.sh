#!/usr/bin/env bash
# Start or resume the `laptop` evidence campaign (docs/results.md), whatever the machine still holds.
#
#   bash tools/campaign.sh            # install what is missing, check out the campaign, train
#   bash tools/campaign.sh --dry-run  # the same, but only list the runs each phase would train
#
# Installs torch and this checkout when they are missing, adds each phase's worktree (one fixed
# commit, outside the repository) when it is gone, and starts the queue in the background, unless
# a campaign.py is already training into the same folder: two phases, one after the other, each
# tools/campaign.py run from its own worktree, so that every experiment trains from one commit.
# Each trains the runs the campaign lacks, two at a time, leaving out those data/laptop holds
# finished, and ships and commits each run into data/laptop the moment it finishes.
#
#   phase 1, from CAMPAIGN_COMMIT (9972821) in CAMPAIGN_WORKTREE (~/campaign): the `laptop`
#     budget's runs, then further seeds beyond them (tools/campaign.py's DEFAULT_SEEDS: main's
#     seeds 3 and 4, the distractors' seed 2);
#   phase 2, from C5_COMMIT in CAMPAIGN_C5_WORKTREE (~/campaign-c5): the sensory failure on a
#     mastered module (`--only 'sensor_failure_mastered/*'`), which 9972821 does not know, into
#     the same output folder. It starts when phase 1 ends, reading C5_COMMIT from this file then;
#     while C5_COMMIT is the placeholder TO_BE_SET, it refuses to start and says so.
#
# A campaign.py started from an earlier checkout goes on with its own queue until it ends: this
# script starts the new one once it has (or once it is stopped; the runs in flight resume from
# their checkpoints). Settings (environment): CAMPAIGN_COMMIT, CAMPAIGN_WORKTREE,
# CAMPAIGN_C5_COMMIT (overrides C5_COMMIT), CAMPAIGN_C5_WORKTREE, CAMPAIGN_RUNS.
# The background job is `campaign.sh --queue` (phase 1, then `campaign.sh --phase2`, which runs
# phase 2 alone in the foreground).
set -euo pipefail

# The commit `sensor_failure_mastered` trains from: set it once that experiment is merged.
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
    phase2=(--only 'sensor_failure_mastered/*')

    case "$mode" in
        "" | --dry-run | --queue | --phase2) ;;
        *) echo "campaign.sh: unknown option $mode (--dry-run)" >&2; return 2 ;;
    esac
    python -c "import torch" 2>/dev/null || python -m pip install -q torch==2.13.0
    python -c "import curious, dagster, pytest" 2>/dev/null || python -m pip install -q -e "$repo[test]"

    case "$mode" in
        --dry-run)
            checkout "$worktree" "$commit"
            echo "phase 1, from ${commit} in $worktree:"
            in_worktree "$worktree" "${queue[@]}" --dry-run
            if c5_set "$c5_commit"; then
                checkout "$c5_worktree" "$c5_commit"
                echo "phase 2, from ${c5_commit} in $c5_worktree, once phase 1 ends:"
                in_worktree "$c5_worktree" "${queue[@]}" "${phase2[@]}" --dry-run
            else
                echo "phase 2, sensor_failure_mastered/*: $(c5_refusal)"
            fi
            ;;
        --queue)
            checkout "$worktree" "$commit"
            echo "campaign.sh: phase 1 from ${commit} in $worktree, $(date -u '+%F %T UTC')"
            in_worktree "$worktree" "${queue[@]}"
            # read anew, so that a C5_COMMIT set while phase 1 trained is the one phase 2 uses
            exec bash "$repo/tools/campaign.sh" --phase2
            ;;
        --phase2)
            if ! c5_set "$c5_commit"; then
                echo "campaign.sh: phase 2 not started: $(c5_refusal)" >&2
                return 2
            fi
            refuse_if_training "$runs"
            checkout "$c5_worktree" "$c5_commit"
            echo "campaign.sh: phase 2 from ${c5_commit} in $c5_worktree, $(date -u '+%F %T UTC')"
            in_worktree "$c5_worktree" "${queue[@]}" "${phase2[@]}"
            ;;
        "")
            checkout "$worktree" "$commit"
            if c5_set "$c5_commit"; then
                checkout "$c5_worktree" "$c5_commit"
            else
                echo "campaign.sh: phase 1 only for now; phase 2 will not start: $(c5_refusal)"
            fi
            if pgrep -f "tools/campaign.py --out $runs/laptop" >/dev/null; then
                echo "campaign.sh: the campaign is already training (pgrep -af tools/campaign.py)"
                return 0
            fi
            mkdir -p "$runs"
            nohup nice -n 5 bash "$repo/tools/campaign.sh" --queue >>"$runs/laptop-main.log" 2>&1 &
            local then="then phase 2 from ${c5_commit} in $c5_worktree"
            c5_set "$c5_commit" || then="then phase 2 if C5_COMMIT is set when it ends"
            echo "campaign.sh: training (pid $!) phase 1 from ${commit} in $worktree, $then;" \
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

c5_set() {
    [ "$1" != TO_BE_SET ]
}

c5_refusal() {
    echo "C5_COMMIT is still the placeholder TO_BE_SET: set it at the top of" \
         "tools/campaign.sh to the commit that defines sensor_failure_mastered, then run" \
         "bash tools/campaign.sh again"
}

# refuse_if_training RUNS: stop where a campaign.py already trains into RUNS/laptop.
refuse_if_training() {
    if pgrep -f "tools/campaign.py --out $1/laptop" >/dev/null; then
        echo "campaign.sh: the campaign is already training (pgrep -af tools/campaign.py)" >&2
        exit 2
    fi
}

# one line, read whole before it runs: the file may be edited (C5_COMMIT set) while it trains
main "$@"; exit $?
