"""Whether a window can open here: the native Rerun viewer needs a display.

Shared by `curious view` (which opens the viewer, or says how to look elsewhere) and the
recorder's live viewer (`curious train --spawn-viewer`, which only writes the file without one).
"""

from __future__ import annotations

import os
import sys


def has_display() -> bool:
    """False on Linux without X11 or Wayland (`DISPLAY` and `WAYLAND_DISPLAY` unset), where a
    native viewer cannot open a window; True elsewhere."""
    if not sys.platform.startswith("linux"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
