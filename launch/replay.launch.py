"""ros2 launch for replaying a recorded bag through a scene's nodes: the sensor node republishes
the bag's image topic as raw CDR with /clock, and every other node runs on bag time
(use_sim_time). See unitac_launch.py.

ros2 launch <this file> bag:=/path/to/bag scene:=fabric_selection rate:=1.0
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import unitac_launch  # noqa: E402

SCENE = None  # the `scene` argument
OVERRIDES = {"source": "bag", "use_sim_time": "true"}


def generate_launch_description():
    return unitac_launch.description(SCENE, OVERRIDES)
