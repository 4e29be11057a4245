"""A 5 cm cube of mass 2 (the Fetch block), as a composer entity."""

from __future__ import annotations

from dm_control import mjcf

from suite import layout
from suite.dm_composer import composer

# Reachable cubes: cube 1 (manipulated) red, cube 2 (base) blue, cube 3 green; distractors grey.
CUBE_COLOURS = ((0.85, 0.2, 0.2, 1.0), (0.2, 0.35, 0.85, 1.0), (0.2, 0.65, 0.3, 1.0))
DISTRACTOR_COLOUR = (0.45, 0.45, 0.45, 1.0)


class Cube(composer.Entity):
    """A box-shaped free body; the arena attaches it with a free joint."""

    def _build(self, name: str, rgba: tuple[float, float, float, float]) -> None:
        self._mjcf_root = mjcf.RootElement(model=name)
        half = layout.CUBE_HALF_SIZE
        self._geom = self._mjcf_root.worldbody.add(
            "geom",
            name="box",
            type="box",
            size=(half, half, half),
            mass=layout.CUBE_MASS,
            condim=3,
            rgba=rgba,
        )

    @property
    def mjcf_model(self) -> mjcf.RootElement:
        return self._mjcf_root

    @property
    def geom(self) -> mjcf.Element:
        return self._geom


def cube_colour(index: int, reachable: bool = True) -> tuple[float, float, float, float]:
    """The colour of cube `index` (0-based): red, blue, green while reachable; distractors grey."""
    return CUBE_COLOURS[index] if reachable and index < len(CUBE_COLOURS) else DISTRACTOR_COLOUR
