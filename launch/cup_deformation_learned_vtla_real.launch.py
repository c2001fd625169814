"""ros2 launch for the cup_deformation_learned_vtla_real scene (the learned policy) in closed loop: the sim task world node (source:=sim),
then the scene's nodes (contact, inference when the mode needs it, policy), on sim time. See
unitac_launch.py and launch/README.md.

ros2 launch <this file> seed:=1 trial:=0 split:=train
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import unitac_launch  # noqa: E402

SCENE = "cup_deformation_learned_vtla_real"
OVERRIDES = {"source": "sim"}


def generate_launch_description():
    return unitac_launch.description(SCENE, OVERRIDES)
