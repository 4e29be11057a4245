"""What a run was trained with, for config.json's record of every start and resume: the library
versions, the source commit and the machine (`curious.runs.folder.RunFolder.describe` writes them,
`curious.runs.run_info.RunInfo` reads them back)."""

from __future__ import annotations

import contextlib
import os
import platform
import subprocess
from collections.abc import Mapping
from importlib import metadata
from pathlib import Path
from typing import Any


def library_versions() -> dict[str, str | None]:
    """Installed versions of the libraries a run's results depend on."""
    versions: dict[str, str | None] = {"python": platform.python_version()}
    for dist in ("curious", "torch", "numpy", "mujoco", "dm-control", "rerun-sdk"):
        try:
            versions[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            versions[dist] = None
    return versions


def _cpu_model() -> str:
    """The processor's model name (Linux's /proc/cpuinfo), else what `platform` knows."""
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name") and ":" in line:
                return line.split(":", 1)[1].strip()
    return platform.processor() or platform.machine()


def machine(device: str = "cpu") -> dict[str, Any]:
    """What a run starts or resumes on, for the compute an experiment took: the processor, its
    logical cores, the system and, with ``device`` `cuda`, the GPU (no host name)."""
    gpu = None
    if device.startswith("cuda"):
        import torch

        if torch.cuda.is_available():
            gpu = torch.cuda.get_device_name(torch.device(device))
    affinity = getattr(os, "sched_getaffinity", None)  # the cores this process may use (Linux)
    cores = len(affinity(0)) if affinity is not None else os.cpu_count()
    return {
        "cpu": _cpu_model(),
        "cores": cores,
        "system": f"{platform.system()} {platform.release()}",
        "gpu": gpu,
    }


def machine_text(entry: Mapping[str, Any]) -> str:
    """One line for a `machine` entry, e.g. ``AMD EPYC 7B13, 2 cores``; empty where none."""
    if not entry.get("cpu"):
        return ""
    text = str(entry["cpu"])
    if entry.get("cores"):
        text += f", {entry['cores']} cores"
    if entry.get("gpu"):
        text += f", {entry['gpu']}"
    return text


def git_commit() -> dict[str, Any]:
    """Commit (and whether the tree has changes) of the source tree this package runs from."""
    root = Path(__file__).resolve().parent.parent
    try:
        commit = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        ).stdout.strip()
        status = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        ).stdout
        return {"commit": commit, "dirty": bool(status.strip())}
    except (OSError, subprocess.SubprocessError):
        return {"commit": None, "dirty": None}
