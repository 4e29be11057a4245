#!/usr/bin/env bash
# Wheels for a node that cannot reach a package index but already has torch, numpy, pandas,
# pyarrow, scipy and tqdm (a GPU node's image, say): what `curious train` and
# `tools/gpu_checks.sh` need beyond those, for that node's Python, in one folder small enough to
# copy along with the repository. dm-control's and gymnasium-robotics' wheels carry models the
# suite never loads (dm-control's locomotion and dog assets, gymnasium-robotics' Adroit hand and
# Franka kitchen: about 80 of their 83 MB); they are left out of the copies written here.
#
#   bash tools/offline_wheels.sh DIR                       # for Python 3.12 on x86-64 Linux
#   PYTHON_VERSION=3.11 bash tools/offline_wheels.sh DIR
#
# On the node, from the repository's root:
#   python3 -m pip install --no-index --no-deps --target /tmp/site DIR/*.whl
#   export PYTHONPATH=/tmp/site:$PWD
#   bash tools/gpu_checks.sh OUT
# (Rerun, Dagster and Ray are not among them: training with --no-record, the benchmarks and the
# CUDA tests need none of them.)
set -euo pipefail

dir=${1:?usage: bash tools/offline_wheels.sh DIR}
version=${PYTHON_VERSION:-3.12}
mkdir -p "$dir"
platforms=()
for tag in manylinux_2_35 manylinux_2_34 manylinux_2_31 manylinux_2_28 manylinux_2_27 \
    manylinux_2_24 manylinux_2_17 manylinux2014; do
    platforms+=(--platform "${tag}_x86_64")
done
# the versions pyproject.toml pins, and the unpinned needs of mujoco and dm-control
pins=$(python3 - <<'EOF'
import re
import tomllib

deps = tomllib.load(open("pyproject.toml", "rb"))["project"]["dependencies"]
wanted = ("mujoco", "dm-control", "gymnasium-robotics")
print(" ".join(d for d in deps if re.split(r"[=<>]", d)[0] in wanted))
EOF
)
# shellcheck disable=SC2086
python3 -m pip download -q --no-deps --only-binary=:all: --python-version "$version" \
    --implementation cp "${platforms[@]}" -d "$dir" $pins dm-env dm-tree glfw pyopengl

python3 - "$dir" <<'EOF'
import sys
import zipfile
from pathlib import Path

UNUSED = {  # package folders the suite never reads
    "dm_control": ("dm_control/locomotion/", "dm_control/suite/dog_assets/",
                   "dm_control/mujoco/testing/", "dm_control/mjcf/test_assets/",
                   "dm_control/blender/"),
    "gymnasium_robotics": ("gymnasium_robotics/envs/assets/adroit_hand/",
                           "gymnasium_robotics/envs/assets/kitchen_franka/"),
}  # fmt: skip
for wheel in sorted(Path(sys.argv[1]).glob("*.whl")):
    drop = UNUSED.get(wheel.name.split("-")[0])
    if drop is None:
        continue
    slim = wheel.with_suffix(".slim")
    with zipfile.ZipFile(wheel) as src, zipfile.ZipFile(slim, "w", zipfile.ZIP_DEFLATED) as out:
        for info in src.infolist():
            if info.filename.startswith(drop):
                continue
            data = src.read(info)
            if info.filename.endswith(".dist-info/RECORD"):  # the files it lists are the wheel's
                lines = data.decode().splitlines()
                data = "\n".join(l for l in lines if not l.startswith(drop)).encode() + b"\n"
            out.writestr(info, data)
    before = wheel.stat().st_size
    slim.replace(wheel)
    print(f"{wheel.name}: {before / 1e6:.1f} MB, {wheel.stat().st_size / 1e6:.1f} MB without unused models")
EOF
du -sh "$dir"
