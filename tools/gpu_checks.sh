#!/usr/bin/env bash
# The checks a GPU node owes the project (docs/scaling.md). STEPS picks the steps; the default,
# "seeds tests", is the benchmark of runs side by side and the CUDA tests, whose time limits
# (400 s and 140 s) fit one device call of 10 minutes with the wheels' install. "bench one side"
# (the cycle benchmark and the runs) and "resume" are a second call's; "tests bench one side" took 309 s on a 16-core node with
# an H100 (node D of docs/benchmarks.md, 2026-11-26, three contenders, two runs side by side):
#
#   bash tools/gpu_checks.sh OUT            # on a node with a CUDA device: results into OUT/
#   STEPS="bench one side" bash tools/gpu_checks.sh OUT    # steps 2-4
#   PRESET=smoke DEVICE=cpu bash tools/gpu_checks.sh OUT   # the same steps on a CPU
#
# A node that has torch but not the suite's libraries and cannot reach a package index takes
# them as wheels made beside the repository (`bash tools/offline_wheels.sh DIR`, which says how
# to install them there).
#
# 0. (STEPS with "seeds") `curious bench seeds`: SEEDS_RUNS (15) `paper` runs side by side, as one
#    `curious train --seeds` against as many processes started at once, into OUT/seeds.json;
# 0b. (STEPS with "long") the SEEDS_RUNS processes alone over LONG_CYCLES (40) cycles a
#    run, once for each learner backend of LONG_BACKENDS ("autograd compiled"), into
#    OUT/long-BACKEND.json: each cycle's seconds and the rate over the second half of the cycles
#    tell the compiled learner's warm-up from its steady rate (docs/scaling.md); with MPS=1 the
#    whole step runs under the MPS server, as `curious reproduce --device cuda` is advised to;
# 1. (STEPS with "tests") the CUDA tests (-k cuda of the learner's, the runs' and the seeds'
#    tests), into OUT/cuda-tests.txt;
# 2. (STEPS with "bench") `curious bench cycle` of the GPU node's contenders, into OUT/bench.json;
# 3. (STEPS with "one") one short run with a worker process per core and prefetched minibatches
#    (the autograd update), into OUT/one-run/;
# 4. (STEPS with "side") for each N of SIDE_BY_SIDE, N such runs side by side, each with 1/N of
#    the cores, into OUT/N-runs/ (what several runs sharing one node give: docs/scaling.md's
#    projections of the whole reproduction rest on it);
# 5. (STEPS with "resume") one run stopped by a time limit, as a node's time limit ends it,
#    then resumed from its last checkpoint with --resume and stopped again: OUT/resume/ holds its
#    metrics, both logs and, after each stop, the checkpoints and replay segments it held
#    (listings and each checkpoint's replay.json; the run folder itself stays in RESUME_DIR).
# Each step has a time limit of its own, so that a slow one leaves the others their turn;
# OUT/env.txt says on what it ran, and where runs were trained the script prints each run's
# episodes/s. Settings (environment): PRESET (paper), DEVICE (cuda), EPISODES (1900, two epochs of
# `paper`), CONTENDERS (workers_prefetch,workers_compiled,workers_prefetch_compiled,ours_gpu),
# SIDE_BY_SIDE (2; "2 4 8" adds four and eight runs, N runs each within 80 + 25 N s), STEPS
# ("seeds tests"), LONG_CYCLES (40), LONG_BACKENDS ("autograd compiled"), LONG_SECONDS (260:
# each backend's time limit in step 0b), SEEDS_RUNS (15), SEEDS_CYCLES (3), SEEDS_SET (settings
# for every run, e.g. "learner_backend=compiled"), SEEDS_SECONDS (400: step 0's time limit), MPS
# (1: every step under NVIDIA's Multi-Process Service, docs/scaling.md), RESUME_SECONDS (170: each
# leg of step 5), RESUME_DIR (/tmp/curious-resume: its run folder, outside OUT).
set -uo pipefail

out=${1:?usage: bash tools/gpu_checks.sh OUT}
preset=${PRESET:-paper}
device=${DEVICE:-cuda}
episodes=${EPISODES:-1900}
contenders=${CONTENDERS:-workers_prefetch,workers_compiled,workers_prefetch_compiled,ours_gpu}
side_by_side=${SIDE_BY_SIDE:-2}
steps=" ${STEPS:-seeds tests} "
wanted() { [[ $steps == *" $1 "* ]]; }
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

if [[ ${MPS:-0} == 1 ]]; then
    # CUDA's Multi-Process Service for every step's processes, stopped when the script ends
    export CUDA_MPS_PIPE_DIRECTORY=/tmp/curious-mps CUDA_MPS_LOG_DIRECTORY=/tmp/curious-mps-log
    mkdir -p "$CUDA_MPS_PIPE_DIRECTORY" "$CUDA_MPS_LOG_DIRECTORY"
    nvidia-cuda-mps-control -d && echo "MPS server started" | tee -a "$out/env.txt"
    trap 'echo quit | nvidia-cuda-mps-control' EXIT
fi

if wanted seeds; then
    step "${SEEDS_RUNS:-15}" runs side by side: curious train --seeds against as many processes
    # each contender's rate reaches seeds.err as it ends, should the limit end the rest
    seeds_set=()
    for setting in ${SEEDS_SET:-}; do seeds_set+=(--set "$setting"); done
    timeout "${SEEDS_SECONDS:-400}" python3 -m curious.cli bench seeds \
        --preset "$preset" --device "$device" --runs "${SEEDS_RUNS:-15}" \
        --cycles "${SEEDS_CYCLES:-3}" "${seeds_set[@]}" --json \
        >"$out/seeds.json" 2>"$out/seeds.err"
    echo "exit $?"
    cat "$out/seeds.json"
fi

if wanted long; then
    for backend in ${LONG_BACKENDS:-autograd compiled}; do
        step "${SEEDS_RUNS:-15}" processes alone, "${LONG_CYCLES:-40}" cycles, "$backend"
        timeout "${LONG_SECONDS:-260}" python3 -m curious.cli bench seeds \
            --preset "$preset" --device "$device" --runs "${SEEDS_RUNS:-15}" \
            --cycles "${LONG_CYCLES:-40}" --peer-only --set "learner_backend=$backend" \
            --json >"$out/long-$backend.json" 2>"$out/long-$backend.err"
        status=$?
        echo "exit $status"
        # the time limit stops the benchmark, not its runs' processes: stop them before the next
        [[ $status == 124 ]] && pkill -f "[c]urious.cli train --preset $preset"
        cat "$out/long-$backend.err"
    done
fi

if wanted tests; then
    step CUDA tests
    timeout 140 python3 -m pytest -p no:cacheprovider -n 0 tests/test_agent_learner.py \
        tests/test_agent_runs.py tests/test_train_seeds.py -k cuda -rs -q \
        >"$out/cuda-tests.txt" 2>&1
    tail -1 "$out/cuda-tests.txt"
fi

if wanted bench; then
    step bench cycle
    timeout 220 python3 -m curious.cli bench cycle --preset "$preset" --device "$device" \
        --cycles 6 --contenders "$contenders" --json >"$out/bench.json" 2>"$out/bench.err"
    echo "exit $?"
fi

common=(--preset "$preset" --device "$device" --no-record --no-progress
        --set prefetch_minibatches=true)
settings=("${common[@]}" --set "total_episodes=$episodes")
if wanted one; then
    step one run, "$cores" worker processes
    timeout 120 python3 -m curious.cli train --out "$out/one-run" "${settings[@]}" \
        --set "env_processes=$cores" >"$out/one-run.log" 2>&1
    echo "exit $?"
fi

wanted side || side_by_side=""
for n in $side_by_side; do
    share=$((cores / n > 1 ? cores / n : 2))
    step "$n" runs side by side, "$share" worker processes each
    for seed in $(seq 0 $((n - 1))); do
        # each run has 1/N of the cores, so N runs need longer (an H100 node: 4 runs ~95 s, 8 ~146 s)
        timeout $((80 + 25 * n)) python3 -m curious.cli train --out "$out/$n-runs/seed-$seed" \
            --seed "$seed" "${settings[@]}" --set "env_processes=$share" \
            >"$out/$n-runs-$seed.log" 2>&1 &
    done
    wait
done

if wanted resume; then
    run=${RESUME_DIR:-/tmp/curious-resume}
    seconds=${RESUME_SECONDS:-170}
    rm -rf "$run"
    mkdir -p "$out/resume"
    held() {  # what the run folder's checkpoints hold after a stop, into OUT/resume/$1.txt
        (cd "$run/checkpoints" && ls -l --time-style=+%T -R . && tail -n +1 ep-*/replay.json) \
            >"$out/resume/$1.txt" 2>&1
    }
    for leg in first resumed; do
        step "$leg" leg, stopped after "$seconds" s
        flag=()
        [[ $leg == resumed ]] && flag=(--resume)
        timeout "$seconds" python3 -m curious.cli train --out "$run" "${flag[@]}" "${common[@]}" \
            --set "env_processes=$cores" >"$out/resume/$leg.log" 2>&1
        echo "exit $?"
        held "$leg"
    done
    cp "$run/metrics.parquet" "$run/tests.parquet" "$run/config.json" "$out/resume/" 2>/dev/null
fi

if find "$out" -name metrics.parquet | grep -q .; then
    step rates
    # each run's episodes/s over its own clock, tests and start included: the project's progress table
    python3 -m curious.cli progress "$out"
    # and its training alone: the episodes after its last epoch's test rollouts (the largest gap)
    python3 - "$out" <<'EOF'
import sys
from pathlib import Path

import pandas as pd

for folder in sorted(Path(sys.argv[1]).glob("**/metrics.parquet")):
    wall = pd.read_parquet(folder, columns=["wall_time"])["wall_time"]
    gaps = wall.diff()
    after = wall.iloc[int(gaps.idxmax()) :]
    rate = (len(after) - 1) / (after.iloc[-1] - after.iloc[0])
    print(
        f"{folder.parent}: {rate:.1f} training episodes/s after its last test rollouts, "
        f"which took {gaps.max():.1f} s"
    )
EOF
fi
step done
