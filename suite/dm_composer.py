"""dm_control's composer for the suite's modules, imported without the warnings filter its
import sets.

Importing `dm_control.composer` runs `warnings.simplefilter('always', DeprecationWarning)`
(dm_control/composer/environment.py) for the whole process: every library's deprecation
warnings then print, every time (torch's inductor, at a compiled learner's first step, 14 lines
about its own modules). The suite's modules import composer from here, where that import runs
inside `warnings.catch_warnings()`, so that loading the suite leaves the process's warning
filters as they were.
"""

from __future__ import annotations

import warnings

with warnings.catch_warnings():
    from dm_control import composer
    from dm_control.composer import environment as composer_environment
    from dm_control.composer.observation import observable
    from dm_control.composer.observation import updater as observation_updater

__all__ = ["composer", "composer_environment", "observable", "observation_updater"]
