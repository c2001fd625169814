"""rclpy peer of the depth topics test (crates/ros/tests/depth.rs).

  depth_peer.py NS SECONDS OUT_DIR COUNT [OVERLAY_NS]
      subscribe (reliable, keep all) to NS/depth (sensor_msgs/Image), NS/points
      (sensor_msgs/PointCloud2) and NS/contact_state; once the contact node's depth and points
      publishers are discovered, print "ready" on stderr; collect until COUNT depth images and
      COUNT clouds arrived and 1 s passed with nothing new, or SECONDS passed. Each message's
      serialized bytes go to OUT_DIR/depth_NNNN.cdr and OUT_DIR/points_NNNN.cdr (arrival order);
      stdout gets one JSON object: per depth image what a ROS user sees (encoding, sizes,
      frame_id, NaN count, deepest known value), per cloud its layout and points (count, z range,
      x and y extent), per contact state its stamp and in_contact, and the publisher count of
      NS/contact_overlay (off by default). With OVERLAY_NS (a contact node there with
      `contact.overlay:=true`): also OVERLAY_NS/contact_overlay, waited for like depth, and per
      overlay image its encoding, size, frame_id and the number of outline (255, 0, 0) and
      centroid (255, 255, 0) pixels.

The bytes are decoded by the project's codecs on the Rust side and compared with what the
embedded runtime and bag replay wrote.
"""
import json
import math
import os
import sys
import time

import numpy as np
import rclpy
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Image, PointCloud2
from unitac_msgs.msg import ContactState


def stamp(h):
    return h.stamp.sec * 1_000_000_000 + h.stamp.nanosec


def depth_summary(m):
    a = np.frombuffer(bytes(m.data), dtype="<f4")
    known = a[np.isfinite(a)]
    return {"stamp": stamp(m.header), "frame_id": m.header.frame_id, "encoding": m.encoding,
            "width": m.width, "height": m.height, "step": m.step,
            "is_bigendian": m.is_bigendian, "values": int(a.size),
            "nan": int(np.isnan(a).sum()),
            "max_m": float(known.max()) if known.size else None,
            "min_m": float(known.min()) if known.size else None}


def points_summary(m):
    fields = [[f.name, f.offset, f.datatype, f.count] for f in m.fields]
    p = np.frombuffer(bytes(m.data), dtype="<f4").reshape(-1, 3) if m.data else np.zeros((0, 3))
    return {"stamp": stamp(m.header), "frame_id": m.header.frame_id, "height": m.height,
            "width": m.width, "point_step": m.point_step, "row_step": m.row_step,
            "is_dense": m.is_dense, "fields": fields, "points": int(p.shape[0]),
            "finite": bool(np.isfinite(p).all()),
            "z_min": float(p[:, 2].min()) if p.size else None,
            "x_span": float(p[:, 0].max() - p[:, 0].min()) if p.size else None,
            "y_span": float(p[:, 1].max() - p[:, 1].min()) if p.size else None}


def overlay_summary(m):
    a = np.frombuffer(bytes(m.data), dtype=np.uint8).reshape(m.height, m.step)[:, :m.width * 3]
    px = a.reshape(-1, 3)
    count = lambda c: int((px == np.array(c, dtype=np.uint8)).all(axis=1).sum())
    return {"stamp": stamp(m.header), "frame_id": m.header.frame_id, "encoding": m.encoding,
            "width": m.width, "height": m.height, "outline": count([255, 0, 0]),
            "centroid": count([255, 255, 0])}


def main():
    ns, seconds, out_dir, count = sys.argv[1], float(sys.argv[2]), sys.argv[3], int(sys.argv[4])
    overlay_ns = sys.argv[5] if len(sys.argv) > 5 else None
    os.makedirs(out_dir, exist_ok=True)
    rclpy.init()
    try:
        node = Node("unitac_depth_peer")
        got = {"depth": [], "points": [], "contact_state": [], "overlay": []}
        last = [time.monotonic()]
        n = {"depth": 0, "points": 0}

        def keep(topic, summary):
            def cb(m):
                with open(os.path.join(out_dir, f"{topic}_{n[topic]:04d}.cdr"), "wb") as f:
                    f.write(serialize_message(m))
                n[topic] += 1
                got[topic].append(summary(m))
                last[0] = time.monotonic()
            return cb

        qos = QoSProfile(history=HistoryPolicy.KEEP_ALL)
        node.create_subscription(Image, f"{ns}/depth", keep("depth", depth_summary), qos)
        node.create_subscription(PointCloud2, f"{ns}/points", keep("points", points_summary), qos)
        node.create_subscription(
            ContactState, f"{ns}/contact_state",
            lambda m: got["contact_state"].append({"stamp": stamp(m.header),
                                                   "in_contact": bool(m.in_contact)}), qos)
        if overlay_ns:
            node.create_subscription(
                Image, f"{overlay_ns}/contact_overlay",
                lambda m: got["overlay"].append(overlay_summary(m)), qos)
        end = time.monotonic() + seconds
        ready = False
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.02)
            if not ready and node.count_publishers(f"{ns}/depth") > 0 \
                    and node.count_publishers(f"{ns}/points") > 0 \
                    and (not overlay_ns
                         or node.count_publishers(f"{overlay_ns}/contact_overlay") > 0):
                ready = True
                print("ready", file=sys.stderr, flush=True)
            done = n["depth"] >= count and n["points"] >= count \
                and (not overlay_ns or len(got["overlay"]) >= count)
            if done and time.monotonic() - last[0] > 1.0:
                break
        got["overlay_publishers"] = node.count_publishers(f"{ns}/contact_overlay")
        print(json.dumps(got, allow_nan=False, default=lambda x: None
                         if isinstance(x, float) and math.isnan(x) else x))
        return 0
    finally:
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
