"""ros2 launch for a real arm that already runs ros2_control: our nodes only (the V4L2 sensor,
contact, inference when the scene needs it, the policy), the gripper through the robot's
control_msgs/action/GripperCommand server, its state from the robot's joint_states, and the
sensor's static transforms when the robot's URDF lacks the sensor (tf:=true). No sim node and no
gripper node. See unitac_launch.py and launch/README.md ("On a real arm").

ros2 launch <this file> scene:=cup_deformation_vtla_real arm_frame:=base_link \
  gripper_action:=/gripper_controller/gripper_cmd gripper_joint:=<joint> sensor_serial:=<serial>
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import unitac_launch  # noqa: E402

SCENE = None  # the `scene` argument
OVERRIDES = {"scene": "cup_deformation_vtla_real", "source": "v4l", "gripper": "action"}
# This file's argument names for the planner's: on a robot "serial" could be anything's.
RENAMED = {"sensor_serial": "serial"}


def generate_launch_description():
    return unitac_launch.description(SCENE, OVERRIDES, RENAMED)
