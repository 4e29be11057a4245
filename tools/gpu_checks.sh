#!/usr/bin/env bash
# The checks a GPU node owes the project (docs/scaling.md), in one go: about 6-8 minutes on a
# 16-core node with an H100, estimated from what the same measurements took there (2026-11-26);
# the script itself has not run on a GPU yet:
#
#   bash tools/gpu_checks.sh OUT            # on a node with a CUDA device: results into OUT/
#   PRESET=smoke DEVICE=cpu bash tools/gpu_checks.sh OUT   # the same steps on a CPU, in seconds
#
# 1. the CUDA tests (tests/test_agent_learner.py -k cuda), into OUT/cuda-tests.txt;
# 2. `curious bench cycle` of the GPU node's contenders, into OUT/bench.json;
# 3. one short run with the fastest synchronous settings, into OUT/one-run/;
# 4. two such runs side by side, each with half the cores, into OUT/two-runs/ (what several runs
#    sharing one node give: docs/scaling.md's projections of the whole reproduction rest on it).
# Each step has a time limit of its own, so that a slow one leaves the others their turn; OUT/env.txt
# says on what it ran. Settings (environment): PRESET (paper), DEVICE (cuda), EPISODES (1900, two
# epochs of `paper`), CONTENDERS.
set -uo pipefail

out=${1:?usage: bash tools/gpu_checks.sh OUT}
preset=${PRESET:-paper}
device=${DEVICE:-cuda}
episodes=${EPISODES:-1900}
contenders=${CONTENDERS:-workers,workers_prefetch,ours_workers_prefetch,workers_compiled,ours_gpu}
cores=$(nproc)
mkdir -p "$out"
export MUJOCO_GL=disable PYTHONUNBUFFERED=1
start=$(date +%s)
step() { echo "== $(($(date +%s) - start)) s: $*"; }

step environment
{
    date -u
    nvidia-smi -L 2>/dev/null || echo "no nvidia-smi"
    echo "cores $cores"
    python3 -c "import sys, torch, mujoco; print('python', sys.version.split()[0], 'torch', \
torch.__version__, 'cuda', torch.cuda.is_available(), 'mujoco', mujoco.__version__)"
    git rev-parse --short HEAD 2>/dev/null
} 2>&1 | tee "$out/env.txt"

step CUDA tests
timeout 120 python3 -m pytest -p no:cacheprovider tests/test_agent_learner.py -k cuda -rs -q \
    >"$out/cuda-tests.txt" 2>&1
tail -1 "$out/cuda-tests.txt"

step bench cycle
timeout 240 python3 -m curious.cli bench cycle --preset "$preset" --device "$device" --cycles 6 \
    --contenders "$contenders" --json >"$out/bench.json" 2>"$out/bench.err"
echo "exit $?"

settings=(--preset "$preset" --device "$device" --no-record --no-progress
          --set prefetch_minibatches=true --set "total_episodes=$episodes")
step one run, "$cores" worker processes
timeout 150 python3 -m curious.cli train --out "$out/one-run" "${settings[@]}" \
    --set "env_processes=$cores" >"$out/one-run.log" 2>&1
echo "exit $?"

half=$((cores / 2 > 1 ? cores / 2 : 2))
step two runs side by side, "$half" worker processes each
for seed in 0 1; do
    timeout 200 python3 -m curious.cli train --out "$out/two-runs/seed-$seed" --seed "$seed" \
        "${settings[@]}" --set "env_processes=$half" >"$out/two-runs-$seed.log" 2>&1 &
done
wait

step rates
# each run's episodes/s over its own clock, tests and start included: the project's progress table
python3 -m curious.cli progress "$out" | head -n 5
# and its training alone: the episodes after its last epoch's test rollouts (the largest gap)
python3 - "$out" <<'EOF'
import sys
from pathlib import Path

import pandas as pd

for folder in sorted(Path(sys.argv[1]).glob("**/metrics.parquet")):
    wall = pd.read_parquet(folder, columns=["wall_time"])["wall_time"]
    after = wall.iloc[int(wall.diff().idxmax()) :]
    rate = (len(after) - 1) / (after.iloc[-1] - after.iloc[0])
    print(f"{folder.parent}: {rate:.1f} training episodes/s after its last test rollouts")
EOF
step done
