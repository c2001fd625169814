"""rclpy peer for the contact-node tests (crates/ros/tests/nodes.rs).

  contact_peer.py images NS N       publish N sensor_msgs/Image (rgb8, 64x48, best effort) into
                                    NS/image: 15 frames of background, then a bright disc for 10
                                    frames, then background; collect NS/contact_state and
                                    NS/contact_episode; print a JSON summary
  contact_peer.py listen NS SECONDS EPISODES
                                    subscribe to NS/image_raw, NS/contact_state,
                                    NS/contact_episode and /diagnostics until EPISODES episodes
                                    arrived (then 0.5 s more) or SECONDS passed; print a summary
"""
import json
import sys
import time

import numpy as np
import rclpy
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import Image
from unitac_msgs.msg import ContactEpisode, ContactState


def collect(node, ns, extra=None):
    got = {"states": [], "episodes": [], "diag": [], "images": 0, "image_frames": set()}
    node.create_subscription(ContactState, ns + "/contact_state", lambda m: got["states"].append(
        {"in_contact": m.in_contact, "area_px": m.area_px, "frame_id": m.header.frame_id,
         "stamp": m.header.stamp.sec * 10**9 + m.header.stamp.nanosec, "sensor_id": m.sensor_id}), 100)
    node.create_subscription(ContactEpisode, ns + "/contact_episode", lambda m: got["episodes"].append(
        {"id": m.episode_id, "frames": m.frame_count, "peak": m.peak_area_px, "frame_id": m.header.frame_id}), 100)
    node.create_subscription(DiagnosticArray, "/diagnostics", lambda m: got["diag"].extend(
        {"name": s.name, "values": {kv.key: kv.value for kv in s.values}} for s in m.status), 100)
    return got


def images(ns, n):
    node = Node("unitac_contact_peer")
    got = collect(node, ns)
    pub = node.create_publisher(Image, ns + "/image", qos_profile_sensor_data)
    deadline = time.monotonic() + 20
    while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.05)
    time.sleep(0.5)  # let the node's publishers match ours too
    rng = np.random.default_rng(1)
    h, w = 48, 64
    yy, xx = np.mgrid[0:h, 0:w]
    disc = (xx - 32) ** 2 + (yy - 24) ** 2 < 12 ** 2
    for k in range(n):
        img = np.clip(120 + rng.normal(0, 1.0, (h, w, 3)), 0, 255)
        if 15 <= k < 25:
            img[disc] += 40
        m = Image()
        m.header.stamp.sec = 1_700_000_000 + k // 25
        m.header.stamp.nanosec = (k % 25) * 40_000_000
        m.header.frame_id = "gs1_optical_frame"
        m.height, m.width, m.encoding, m.step = h, w, "rgb8", w * 3
        m.data = np.clip(img, 0, 255).astype(np.uint8).tobytes()
        pub.publish(m)
        end = time.monotonic() + 0.04  # 25 fps
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.005)
    end = time.monotonic() + 2.5
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    got.pop("image_frames")
    print(json.dumps(got))
    return 0


def listen(ns, seconds, episodes):
    node = Node("unitac_listen_peer")
    got = collect(node, ns)
    # Subscribe to images (which the sensor node waits for) only once the contact node's
    # publishers are discovered, so no episode is published before we can receive it.
    ready = time.monotonic() + seconds / 2
    while time.monotonic() < ready and not all(
            node.count_publishers(ns + t) > 0 for t in ("/contact_state", "/contact_episode")):
        rclpy.spin_once(node, timeout_sec=0.05)
    node.create_subscription(Image, ns + "/image_raw", lambda m: (got.__setitem__("images", got["images"] + 1),
                                                                 got["image_frames"].add(m.header.frame_id)),
                             qos_profile_sensor_data)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
        if len(got["episodes"]) >= episodes:
            end = min(end, time.monotonic() + 0.5)
    got["image_frames"] = sorted(got["image_frames"])
    print(json.dumps(got))
    return 0


def main():
    rclpy.init()
    try:
        if sys.argv[1] == "images":
            return images(sys.argv[2], int(sys.argv[3]))
        return listen(sys.argv[2], float(sys.argv[3]), int(sys.argv[4]))
    finally:
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
