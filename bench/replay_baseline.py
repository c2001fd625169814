"""Python baseline for `unitac-lab bench replay`: read an rgb8 MCAP bag with rosbags, deserialize each
sensor_msgs/Image, turn it into a numpy array and run the GelSight SDK contact pipeline on it (the
same detect() as bench/contact_baseline.py: colour-difference norm > 15, dilate 7x7, erode
15x15, area and centroid), against the bag's first frame as background. This is what a lab script
replaying a bag in Python does today. Single thread.

usage: replay_baseline.py BAG REPEAT
prints one JSON object: frames per pass, seconds per pass (median), frames/s, versions.
"""
import json
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import rosbags
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore


def main():
    bag, repeat = Path(sys.argv[1]), int(sys.argv[2])
    cv2.setNumThreads(1)
    ts = get_typestore(Stores.ROS2_HUMBLE)
    k_dilate = np.ones((7, 7), np.uint8)
    k_erode = np.ones((15, 15), np.uint8)

    def detect(frame, bg):
        diff = np.linalg.norm(frame.astype(np.float32) - bg, axis=2)
        mask = (diff > 15).astype(np.uint8)
        mask = cv2.erode(cv2.dilate(mask, k_dilate), k_erode)
        ys, xs = np.nonzero(mask)
        if xs.size == 0:
            return 0, (0.0, 0.0)
        return int(xs.size), (float(xs.mean()), float(ys.mean()))

    def one_pass():
        n, contacts, bg = 0, 0, None
        with AnyReader([bag], default_typestore=ts) as r:
            conns = [c for c in r.connections if c.msgtype == 'sensor_msgs/msg/Image']
            for c, _, raw in r.messages(connections=conns):
                m = r.deserialize(raw, c.msgtype)
                frame = np.frombuffer(m.data, np.uint8).reshape(m.height, m.step)[:, : m.width * 3]
                frame = frame.reshape(m.height, m.width, 3)
                if bg is None:
                    bg = frame.astype(np.float32)
                area, _ = detect(frame, bg)
                contacts += area > 0
                n += 1
        return n, contacts

    one_pass()  # warm-up (imports, page cache)
    secs = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        n, contacts = one_pass()
        secs.append(time.perf_counter() - t0)
    secs.sort()
    med = secs[len(secs) // 2]
    print(json.dumps({
        "frames": n,
        "contact_frames": int(contacts),
        "pass_s": med,
        "fps": n / med,
        "rosbags": rosbags.__version__ if hasattr(rosbags, '__version__') else '',
        "numpy": np.__version__,
        "opencv": cv2.__version__,
    }))


if __name__ == "__main__":
    main()
