#!/usr/bin/env bash
# Start or resume the `laptop` evidence campaign (docs/results.md), whatever the machine still holds.
#
#   bash tools/campaign.sh            # install what is missing, check out the campaign, train
#   bash tools/campaign.sh --dry-run  # the same, but only list the runs each lane would train
#
# Installs torch and this checkout when they are missing, adds each experiment's worktree (one
# fixed commit, outside the repository) when it is gone, and starts two lanes in the background,
# each one run at a time (one core each), unless that lane is already training. A lane is a list
# of steps, each tools/campaign.py from the worktree of its experiment's commit, so that every
# experiment trains from one commit; each step trains the runs it names that data/laptop does
# not hold finished (a run folder part-way resumes from its last checkpoint), and ships and
# commits each run into data/laptop the moment it finishes. A step with nothing left to train
# ends at once, so a lane started again goes on where it stopped.
#
#   lane a: the long runs (C3 at the paper's 300,000 episodes), seeds 0, 1 and 2, from
#     LONG_COMMIT in CAMPAIGN_LONG_WORKTREE (~/campaign-long); then the distractors' seed 3
#     (C4 to five seeds a side), from MAIN_COMMIT in CAMPAIGN_WORKTREE (~/campaign); then
#     signed LP on the mastered sensory failure (signed_lp, beyond the paper), from
#     BEYOND_COMMIT in CAMPAIGN_BEYOND_WORKTREE (~/campaign-beyond).
#   lane b: the study on a mastered module's seeds 3 and 4 (C5 to five seeds a side), from
#     C5_COMMIT in CAMPAIGN_C5_WORKTREE (~/campaign-c5); then the long runs' seeds 3 and 4,
#     from LONG_COMMIT; then the distractors' seed 4, from MAIN_COMMIT; then LP's two uses
#     apart (lp_uses, beyond the paper), from BEYOND_COMMIT.
# The long runs come first (the claim no run has tested); C5's runs share the first stretch of
# lane b because they are shorter (120,000 episodes against 300,000), so a machine lost mid-run
# loses less of them, and C5 needs them for its test; C4's seeds come after both, and the
# experiments beyond the paper after every run of the paper's claims (docs/results.md, "The
# campaign's runs"). The earlier phases of the campaign (the budget's runs, the study on a
# mastered module's seeds 0-2, the distractors' seed 2 and main's seeds 3 and 4) are all shipped.
#
# Before a lane starts, each of its steps records the seeds it adds beyond the budget's in the
# runs' reproduce.json (`campaign.py --plan-only`), so that `curious progress` counts the whole
# plan.
#
# Settings (environment): CAMPAIGN_RUNS (~/curious-runs), CAMPAIGN_WORKTREE,
# CAMPAIGN_C5_WORKTREE, CAMPAIGN_LONG_WORKTREE, CAMPAIGN_BEYOND_WORKTREE. Logs: $CAMPAIGN_RUNS/laptop-lane-{a,b}.log. The
# background jobs are `campaign.sh --lane a` and `campaign.sh --lane b`.
set -euo pipefail

# The commits the experiments train from: main, distractors and sensor_failure; the study on a
# mastered module (sensor_failure_mastered); the long runs (long); the experiments beyond the
# paper (lp_uses, signed_lp).
MAIN_COMMIT=9972821
C5_COMMIT=8d18b17
LONG_COMMIT=24d01ae
BEYOND_COMMIT=ab4c202

main() {
    local mode=${1:-}
    repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
    runs=${CAMPAIGN_RUNS:-$HOME/curious-runs}
    main_tree=${CAMPAIGN_WORKTREE:-$HOME/campaign}
    c5_tree=${CAMPAIGN_C5_WORKTREE:-$HOME/campaign-c5}
    long_tree=${CAMPAIGN_LONG_WORKTREE:-$HOME/campaign-long}
    beyond_tree=${CAMPAIGN_BEYOND_WORKTREE:-$HOME/campaign-beyond}
    queue=(python "$repo/tools/campaign.py" --out "$runs/laptop" --shipped "$repo/data/laptop"
           --ship --set torch_threads=1 --workers 1)

    case "$mode" in
        "" | --dry-run) ;;
        --lane)
            case "${2:-}" in
                a | b) ;;
                *) echo "campaign.sh: --lane takes a or b" >&2; return 2 ;;
            esac
            ;;
        *) echo "campaign.sh: unknown option $mode (--dry-run)" >&2; return 2 ;;
    esac
    python -c "import torch" 2>/dev/null || python -m pip install -q torch==2.13.0
    # from /, so that the checkout itself on the path does not pass for an installed curious
    (cd / && python -c "import curious, dagster, pytest" 2>/dev/null) ||
        python -m pip install -q -e "$repo[test]"
    checkout "$main_tree" "$MAIN_COMMIT"
    checkout "$c5_tree" "$C5_COMMIT"
    checkout "$long_tree" "$LONG_COMMIT"
    checkout "$beyond_tree" "$BEYOND_COMMIT"

    case "$mode" in
        --dry-run)
            for lane in a b; do
                echo "lane $lane:"
                lane_steps "$lane" --dry-run
            done
            ;;
        --lane)
            echo "campaign.sh: lane $2, $(date -u '+%F %T UTC')"
            lane_steps "$2"
            echo "campaign.sh: lane $2 done, $(date -u '+%F %T UTC')"
            ;;
        "")
            mkdir -p "$runs"
            for lane in a b; do
                if pgrep -f "tools/campaign.sh --lane $lane" >/dev/null; then
                    echo "campaign.sh: lane $lane is already training (pgrep -af campaign)"
                    continue
                fi
                # its steps' seeds beyond the budget's into reproduce.json first, so that
                # `curious progress` counts the whole plan, not only the steps begun
                lane_steps "$lane" --plan-only >/dev/null ||
                    echo "campaign.sh: lane $lane's plan not recorded; it trains all the same" >&2
                nohup nice -n 5 bash "$repo/tools/campaign.sh" --lane "$lane" \
                    >>"$runs/laptop-lane-$lane.log" 2>&1 &
                echo "campaign.sh: lane $lane training (pid $!), log $runs/laptop-lane-$lane.log"
                sleep 15  # the two lanes' first writes of reproduce.json one after the other
            done
            echo "campaign.sh: runs in $runs/laptop; \`curious progress $runs/laptop" \
                 "$repo/data/laptop --at-once 2\` says how far they are"
            ;;
    esac
}

# lane_steps LANE [--dry-run]: the lane's steps, one after the other.
lane_steps() {
    local lane=$1
    shift
    local step=(--seeds none)
    case "$lane" in
        a)
            in_worktree "$long_tree" "${queue[@]}" "${step[@]}" "$@" \
                --only 'long/curious/seed-0' --only 'long/curious/seed-1' \
                --only 'long/curious/seed-2'
            in_worktree "$main_tree" "${queue[@]}" --seeds distractors=0-3 "$@" \
                --only 'distractors/*/seed-3'
            in_worktree "$beyond_tree" "${queue[@]}" "${step[@]}" "$@" --only 'signed_lp/*'
            ;;
        b)
            in_worktree "$c5_tree" "${queue[@]}" --seeds sensor_failure_mastered=0-4 "$@" \
                --only 'sensor_failure_mastered/*'
            in_worktree "$long_tree" "${queue[@]}" "${step[@]}" "$@" \
                --only 'long/curious/seed-3' --only 'long/curious/seed-4'
            in_worktree "$main_tree" "${queue[@]}" --seeds distractors=0-4 "$@" \
                --only 'distractors/*/seed-4'
            in_worktree "$beyond_tree" "${queue[@]}" "${step[@]}" "$@" --only 'lp_uses/*'
            ;;
    esac
}

# checkout DIR COMMIT: add the worktree DIR at COMMIT when it is gone; refuse one elsewhere or
# with local changes.
checkout() {
    local dir=$1 commit=$2 head
    if [ ! -d "$dir" ]; then
        git -C "$repo" worktree prune
        git -C "$repo" worktree add --detach "$dir" "$commit" >/dev/null
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

# one line, read whole before it runs: the file may be edited while it trains
main "$@"; exit $?
