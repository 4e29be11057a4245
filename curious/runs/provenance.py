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


def _cpuinfo() -> dict[str, str]:
    """The first processor's fields of Linux's /proc/cpuinfo (empty elsewhere)."""
    fields: dict[str, str] = {}
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if not line.strip():
                break  # the end of the first processor's block
            key, sep, value = line.partition(":")
            if sep:
                fields.setdefault(key.strip(), value.strip())
    return fields


def _cpu_generation(fields: Mapping[str, str]) -> str | None:
    """Family, model and the widest vector instructions, e.g. ``family 25 model 1, AVX2``: what
    tells apart the generations behind one model name (a virtual machine's ``AMD EPYC`` may be
    any of them, and a run's pace differs with it); None where /proc/cpuinfo does not say."""
    if "cpu family" not in fields or "model" not in fields:
        return None
    flags = set(fields.get("flags", "").split())
    vector = next((v for v in ("avx512f", "avx2", "avx") if v in flags), None)
    text = f"family {fields['cpu family']} model {fields['model']}"
    return f"{text}, {vector.removesuffix('f').upper()}" if vector else text


def machine(device: str = "cpu") -> dict[str, Any]:
    """What a run starts or resumes on, for the compute an experiment took: the processor (its
    model name and generation), its logical cores, the system and, with ``device`` `cuda`, the
    GPU (no host name)."""
    gpu = None
    if device.startswith("cuda"):
        import torch

        if torch.cuda.is_available():
            gpu = torch.cuda.get_device_name(torch.device(device))
    affinity = getattr(os, "sched_getaffinity", None)  # the cores this process may use (Linux)
    cores = len(affinity(0)) if affinity is not None else os.cpu_count()
    fields = _cpuinfo()
    return {
        "cpu": fields.get("model name") or platform.processor() or platform.machine(),
        "cpu_generation": _cpu_generation(fields),
        "cores": cores,
        "system": f"{platform.system()} {platform.release()}",
        "gpu": gpu,
    }


def machine_text(entry: Mapping[str, Any]) -> str:
    """One line for a `machine` entry, e.g. ``AMD EPYC (family 25 model 1, AVX2), 2 cores``
    (entries written before the generation was recorded: ``AMD EPYC, 2 cores``); empty where
    none."""
    if not entry.get("cpu"):
        return ""
    text = str(entry["cpu"])
    if entry.get("cpu_generation"):
        text += f" ({entry['cpu_generation']})"
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
