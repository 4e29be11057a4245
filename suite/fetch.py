"""The Fetch arm as a composer entity, built from the MJCF and meshes of gymnasium-robotics.

The model files are read at run time from the installed `gymnasium_robotics` package (they are
not copied into this repository). The Fetch scene files mix the robot with their own table,
block and mocap body, so the robot is assembled here from the pieces that belong to it: the
meshes and materials, the default classes, the contact exclusions, the robot's bodies and the
two finger actuators. Two changes to the robot itself:

- the mocap body is left out: MuJoCo requires mocap bodies to be children of the world body, so
  the arena owns it and the task welds it to the gripper;
- the mobile base's three slide joints (damped by 1e11, i.e. frozen) are removed and the base is
  placed where the Fetch envs park it, which saves three degrees of freedom per physics step.
"""

from __future__ import annotations

import importlib.util
import xml.etree.ElementTree as ET
from pathlib import Path

from dm_control import mjcf

from suite import layout
from suite.dm_composer import composer

_BASE_BODY = "robot0:base_link"
_BASE_SLIDES = ("robot0:slide0", "robot0:slide1", "robot0:slide2")
_SCENE_MATERIALS = ("floor_mat", "table_mat", "block_mat", "puck_mat")


def fetch_asset_dir() -> Path:
    """The `envs/assets` folder of the installed gymnasium-robotics package.

    Found without importing the package (its import is slow and prints warnings).
    """
    spec = importlib.util.find_spec("gymnasium_robotics")
    if spec is None or spec.origin is None:
        raise ModuleNotFoundError(
            "gymnasium-robotics is not installed; the suite loads the Fetch robot's MJCF and "
            "meshes from it (pip install gymnasium-robotics==1.4.2)"
        )
    path = Path(spec.origin).parent / "envs" / "assets"
    if not (path / "fetch" / "robot.xml").is_file():
        raise FileNotFoundError(f"no Fetch model under {path}: is gymnasium-robotics complete?")
    return path


def fetch_robot_xml() -> str:
    """The MJCF text of the Fetch robot alone, with absolute mesh paths."""
    assets = fetch_asset_dir()
    fetch = assets / "fetch"
    shared = ET.parse(fetch / "shared.xml").getroot()
    robot = ET.parse(fetch / "robot.xml").getroot()
    scene = ET.parse(fetch / "pick_and_place.xml").getroot()

    out = ET.Element("mujoco", model="fetch")
    ET.SubElement(out, "compiler", angle="radian", meshdir=str(assets / "stls" / "fetch"))
    asset = ET.SubElement(out, "asset")
    for element in shared.find("asset"):
        if element.tag == "mesh" or (
            element.tag == "material" and element.get("name") not in _SCENE_MATERIALS
        ):
            asset.append(element)
    out.append(shared.find("default"))
    out.append(shared.find("contact"))
    worldbody = ET.SubElement(out, "worldbody")
    for body in robot.findall("body"):
        if body.get("mocap") != "true":
            worldbody.append(body)
    out.append(scene.find("actuator"))
    return ET.tostring(out, encoding="unicode")


class FetchArm(composer.Entity):
    """The 7-DoF Fetch arm with its two-finger parallel gripper, on a fixed base."""

    def _build(self, name: str = "fetch") -> None:
        self._mjcf_root = mjcf.from_xml_string(fetch_robot_xml())
        self._mjcf_root.model = name
        base = self._mjcf_root.find("body", _BASE_BODY)
        for joint_name in _BASE_SLIDES:
            self._mjcf_root.find("joint", joint_name).remove()
        base.pos = layout.FETCH_BASE_POS
        self._gripper_body = self._mjcf_root.find("body", "robot0:gripper_link")
        self._grip_site = self._mjcf_root.find("site", "robot0:grip")
        self._finger_joints = (
            self._mjcf_root.find("joint", "robot0:r_gripper_finger_joint"),
            self._mjcf_root.find("joint", "robot0:l_gripper_finger_joint"),
        )
        self._finger_actuators = (
            self._mjcf_root.find("actuator", "robot0:r_gripper_finger_joint"),
            self._mjcf_root.find("actuator", "robot0:l_gripper_finger_joint"),
        )

    @property
    def mjcf_model(self) -> mjcf.RootElement:
        return self._mjcf_root

    @property
    def gripper_body(self) -> mjcf.Element:
        """The gripper link: the body the mocap weld drives."""
        return self._gripper_body

    @property
    def grip_site(self) -> mjcf.Element:
        """The site between the fingers: the gripper position every module uses."""
        return self._grip_site

    @property
    def finger_joints(self) -> tuple[mjcf.Element, mjcf.Element]:
        """Right and left finger slide joints (0 = closed, 0.05 = open)."""
        return self._finger_joints

    @property
    def finger_actuators(self) -> tuple[mjcf.Element, mjcf.Element]:
        """Right and left finger position actuators."""
        return self._finger_actuators
