"""ros2 launch for the fabric_selection scene: nodes from launch/scenes/fabric_selection.yaml (see unitac_launch.py).

ros2 launch <this file> sensor_id:=gsmini namespace:=left inference:=true
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import unitac_launch  # noqa: E402

SCENE = "fabric_selection"


def generate_launch_description():
    return unitac_launch.description(SCENE)
