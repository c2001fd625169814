"""ros2 launch for any scene in launch/scenes, by name: the nodes the scene's stages need (see
unitac_launch.py and launch/README.md). A scene file added under launch/scenes is launched with
this file and no other edit; a closed-loop scene (one with a policy stage) in the sim with
source:=sim.

ros2 launch <this file> scene:=fabric_selection
ros2 launch <this file> scene:=cup_deformation_vtla_real source:=sim seed:=1 trial:=0
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import unitac_launch  # noqa: E402

SCENE = None  # the `scene` argument


def generate_launch_description():
    return unitac_launch.description(SCENE)
