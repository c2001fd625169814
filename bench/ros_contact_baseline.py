"""Python baseline for `scripts/bench-ros-latency`: the contact node a user would otherwise write,
an rclpy node running the GelSight SDK's (gs_sdk) contact pipeline on each image: the same
detector as bench/contact_baseline.py, background = mean of the first 10 frames (as our node
learns it), ContactState out with the image's header. Same topics and QoS as
our contact node (unitac_stage_node with stages:=contact,slip: image best-effort in,
contact_state reliable out), single thread.

usage: ros_contact_baseline.py --ros-args -r __ns:=/bench
"""
import sys

import cv2
import numpy as np
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Image
from unitac_msgs.msg import ContactState

LEARN_FRAMES = 10


class ContactBaseline(Node):
    def __init__(self):
        super().__init__("unitac_contact")
        cv2.setNumThreads(1)
        self.k_dilate = np.ones((7, 7), np.uint8)
        self.k_erode = np.ones((15, 15), np.uint8)
        self.learn, self.bg, self.seq = [], None, 0
        self.pub = self.create_publisher(ContactState, "contact_state", 10)
        self.create_subscription(Image, "image", self.on_image, qos_profile_sensor_data)

    def on_image(self, m):
        frame = np.frombuffer(m.data, np.uint8).reshape(m.height, m.step)[:, : m.width * 3]
        frame = frame.reshape(m.height, m.width, 3).astype(np.float32)
        self.seq += 1
        if self.bg is None:
            self.learn.append(frame)
            if len(self.learn) == LEARN_FRAMES:
                self.bg = np.mean(self.learn, axis=0)
            return
        diff = np.linalg.norm(frame - self.bg, axis=2)
        mask = cv2.erode(cv2.dilate((diff > 15).astype(np.uint8), self.k_dilate), self.k_erode)
        ys, xs = np.nonzero(mask)
        s = ContactState()
        s.header = m.header
        s.sensor_id = m.header.frame_id.removesuffix("_optical_frame")
        s.frame_seq = self.seq
        s.in_contact = bool(xs.size > 0)
        s.area_px = float(xs.size)
        if xs.size:
            s.centroid_px = [float(xs.mean()), float(ys.mean())]
            s.bbox_px = [int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1]
        self.pub.publish(s)


def main():
    rclpy.init(args=sys.argv)
    node = ContactBaseline()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    rclpy.try_shutdown()


if __name__ == "__main__":
    main()
