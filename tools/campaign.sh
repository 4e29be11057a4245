#!/usr/bin/env bash
# Start or resume the `laptop` evidence campaign (docs/results.md), whatever the machine still holds.
#
#   bash tools/campaign.sh            # install what is missing, check out the campaign, train
#   bash tools/campaign.sh --dry-run  # the same, but only list the runs the queue would train
#
# Installs torch and this checkout when they are missing, adds the campaign's worktree (one fixed
# commit, outside the repository) when it is gone, and starts tools/campaign.py in the background
# from that worktree, unless it is already running: it trains the runs the campaign lacks, two at
# a time, leaving out those data/laptop holds finished, and ships and commits each run into
# data/laptop the moment it finishes. The campaign is the `laptop` budget's runs, then further
# seeds beyond them (tools/campaign.py's DEFAULT_SEEDS: main's seeds 3 and 4, the distractors'
# seed 2), from the same commit. A campaign.py started from an earlier checkout goes
# on with its own queue until it ends: this script starts the new one once it has (or once it is
# stopped; the runs in flight resume from their checkpoints). Settings (environment):
# CAMPAIGN_COMMIT, CAMPAIGN_WORKTREE, CAMPAIGN_RUNS.
set -euo pipefail

commit=${CAMPAIGN_COMMIT:-9972821}
worktree=${CAMPAIGN_WORKTREE:-$HOME/campaign}
runs=${CAMPAIGN_RUNS:-$HOME/curious-runs}
repo=$(cd "$(dirname "$0")/.." && pwd)
dry_run=${1:-}

python -c "import torch" 2>/dev/null || python -m pip install -q torch==2.13.0
python -c "import curious, dagster, pytest" 2>/dev/null || python -m pip install -q -e "$repo[test]"

if [ ! -d "$worktree" ]; then
    git -C "$repo" worktree prune
    git -C "$repo" worktree add --detach "$worktree" "$commit"
fi
head=$(git -C "$worktree" rev-parse HEAD)
if [ "$head" != "$(git -C "$repo" rev-parse "$commit^{commit}")" ]; then
    echo "campaign.sh: $worktree is at ${head:0:7}, not the campaign's $commit: move it away" >&2
    exit 2
fi
if [ -n "$(git -C "$worktree" status --porcelain --untracked-files=no)" ]; then
    echo "campaign.sh: $worktree has local changes: the campaign trains from $commit as it is" >&2
    exit 2
fi

queue=(python "$repo/tools/campaign.py" --out "$runs/laptop" --shipped "$repo/data/laptop"
       --ship --set torch_threads=1)
cd "$worktree"
export PYTHONPATH=$worktree MUJOCO_GL=disable
if [ "$dry_run" = "--dry-run" ]; then
    exec "${queue[@]}" --dry-run
fi
if pgrep -f "tools/campaign.py --out $runs/laptop" >/dev/null; then
    echo "campaign.sh: the campaign is already training (pgrep -af tools/campaign.py)"
    exit 0
fi
mkdir -p "$runs"
nohup nice -n 5 "${queue[@]}" >>"$runs/laptop-main.log" 2>&1 &
echo "campaign.sh: training from ${head:0:7} in $worktree (pid $!), runs in $runs/laptop," \
     "log $runs/laptop-main.log"
