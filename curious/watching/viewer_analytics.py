"""The Rerun viewer that `curious view` starts runs with Rerun's usage analytics off.

Rerun's viewer sends anonymous usage statistics unless its configuration file
(`$XDG_CONFIG_HOME/rerun/analytics.json` on Linux, which `rerun analytics disable` writes) says
otherwise, and prints a notice about them the first time it starts. The viewer this project
starts gets a configuration folder of its own, made for its lifetime, whose file turns the
analytics off (and, being there, keeps the notice away); the user's own Rerun configuration is
neither read nor changed. `CURIOUS_RERUN_ANALYTICS=1` turns them back to Rerun's own settings.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

OPT_IN = "CURIOUS_RERUN_ANALYTICS"
"""Set to 1, the viewer runs with the user's own Rerun configuration (analytics as Rerun's
settings say: `rerun analytics config`)."""


def analytics_config(folder: Path) -> Path:
    """Write Rerun's analytics configuration, turned off, into the configuration folder
    `folder` (what XDG_CONFIG_HOME names); return the file's path."""
    path = folder / "rerun" / "analytics.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    settings = {
        "analytics_enabled": False,
        "analytics_id": "curious-view",
        "metadata": {},
        "config_file_path": str(path),
        "data_dir_path": str(folder / "rerun-analytics-data"),
    }
    path.write_text(json.dumps(settings, indent=2) + "\n", encoding="utf-8")
    return path


@contextlib.contextmanager
def viewer_environment() -> Iterator[dict[str, str] | None]:
    """The environment to start the viewer in (None: this process's own, where the user opted
    in with CURIOUS_RERUN_ANALYTICS=1); the configuration folder it names is removed after."""
    if os.environ.get(OPT_IN, "").strip() == "1":
        yield None
        return
    with tempfile.TemporaryDirectory(prefix="curious-rerun-") as folder:
        analytics_config(Path(folder))
        yield {**os.environ, "XDG_CONFIG_HOME": folder}
