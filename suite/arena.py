"""The scene around the robot: floor, the wide table, the mocap body, lights and cameras."""

from __future__ import annotations

from dm_control import mjcf

from suite import layout
from suite.dm_composer import composer


class TableArena(composer.Arena):
    """A floor and the wide Multi-Task Fetch table, with the Fetch envs' physics options.

    The options matter for speed and behaviour: pyramidal friction cones and no noslip
    iterations (composer's default arena uses elliptic cones with noslip, which is slower and
    not what the Fetch tasks were tuned with).
    """

    def _build(self, name: str = "multi_task_fetch") -> None:
        super()._build(name=name)
        root = self._mjcf_root
        root.option.timestep = layout.PHYSICS_TIMESTEP
        root.option.cone = "pyramidal"
        root.option.noslip_iterations = 0
        root.option.flag.warmstart = "enable"
        root.visual.headlight.ambient = (0.25, 0.25, 0.25)

        root.asset.add(
            "texture",
            name="skybox",
            type="skybox",
            builtin="gradient",
            rgb1=(0.44, 0.85, 0.56),
            rgb2=(0.46, 0.87, 0.58),
            width=32,
            height=32,
        )
        floor_mat = root.asset.add("material", name="floor", rgba=(0.2, 0.2, 0.2, 1))
        table_mat = root.asset.add("material", name="table", rgba=(0.93, 0.93, 0.93, 1))

        root.worldbody.add(
            "geom",
            name="floor",
            type="plane",
            pos=(1.2, 0.75, 0),
            size=(1.6, 1.2, 1),
            material=floor_mat,
            condim=3,
        )
        self._table = root.worldbody.add("body", name="table", pos=layout.TABLE_CENTRE)
        self._table.add(
            "geom", name="table", type="box", size=layout.TABLE_HALF_SIZE, material=table_mat
        )
        # MuJoCo only accepts mocap bodies as children of the world body: the arena owns it.
        self._mocap = root.worldbody.add(
            "body", name="mocap", mocap=True, pos=layout.GRIP0, quat=layout.GRIPPER_QUAT
        )
        self._mocap.add(
            "geom",
            name="mocap",
            type="box",
            size=(0.005, 0.005, 0.005),
            rgba=(0, 0.5, 0, 0.7),
            contype=0,
            conaffinity=0,
            group=5,
        )
        root.worldbody.add(
            "light",
            name="light",
            directional=True,
            pos=(0, 0, 4),
            dir=(0, 0, -1),
            ambient=(0.2, 0.2, 0.2),
            diffuse=(0.8, 0.8, 0.8),
            specular=(0.3, 0.3, 0.3),
            castshadow=False,
        )
        # The Fetch envs' default view (from beyond the table's far right corner, looking back
        # at the robot), moved out to take in the wide table; and a view from above.
        root.worldbody.add(
            "camera", name="front", mode="targetbody", target=self._table, pos=(3.3, -1.15, 1.25)
        )
        root.worldbody.add("camera", name="top", pos=(1.65, 0.75, 2.6), quat=(1, 0, 0, 0))

    @property
    def mocap(self) -> mjcf.Element:
        """The mocap body that the task welds to the gripper."""
        return self._mocap

    @property
    def table(self) -> mjcf.Element:
        return self._table
