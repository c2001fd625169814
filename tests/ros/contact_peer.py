"""rclpy peer for the contact-node tests (crates/ros/tests/nodes.rs).

  contact_peer.py images NS N [FAULTS_JSON]
                                    publish N sensor_msgs/Image (rgb8, 64x48, best effort) into
                                    NS/image: 15 frames of background, then a bright disc for 10
                                    frames, then background; collect NS/contact_state and
                                    NS/contact_episode; print a JSON summary. FAULTS_JSON:
                                    {"negative_sec"|"big_nanosec"|"bad_encoding": [k...]}
  contact_peer.py listen NS SECONDS [OPTIONS_JSON]
                                    subscribe to everything the nodes publish in NS (images,
                                    contact states/episodes/clips, properties, comparisons,
                                    latents) plus /diagnostics and /clock until the counts in
                                    {"until": {...}} arrived (then 0.5 s more) or SECONDS passed;
                                    {"wait_for": [topics]} publishers to discover first;
                                    {"compressed": true} images from NS/image_raw/compressed;
                                    {"visual": {"names": [...], "values": [...]}} publish that
                                    VisualObservation on NS/visual_observation at 5 Hz (a camera);
                                    {"stop_pid", "stop_after", "stop_seconds"} stall a process
                                    (SIGSTOP/SIGCONT) meanwhile; print a summary
  contact_peer.py slow NS SECONDS DELAY
                                    a slow reliable subscriber to NS/image_raw (DELAY s per image)
"""
import json
import os
import signal
import sys
import time

import numpy as np
import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, qos_profile_sensor_data
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import CompressedImage, Image
from rosgraph_msgs.msg import Clock
from unitac_msgs.msg import (ContactClip, ContactEpisode, ContactState, PropertyComparison, VisualObservation,
                             TactileLatent, TactileProperties)


def stamp_ns(h):
    return h.stamp.sec * 10**9 + h.stamp.nanosec


def collect(node, ns):
    """Subscribe to everything the nodes publish; return the dict the callbacks fill."""
    got = {"states": [], "episodes": [], "clips": [], "properties": [], "comparisons": [],
           "latents": [], "diag": [], "clock": [], "images": 0, "image_frames": set(),
           "image_times": []}
    t0 = time.monotonic()
    got["t0"] = t0
    sub = node.create_subscription
    sub(ContactState, ns + "/contact_state", lambda m: got["states"].append(
        {"in_contact": m.in_contact, "area_px": m.area_px, "frame_id": m.header.frame_id,
         "stamp": stamp_ns(m.header), "sensor_id": m.sensor_id}), 100)
    sub(ContactEpisode, ns + "/contact_episode", lambda m: got["episodes"].append(
        {"id": m.episode_id, "frames": m.frame_count, "peak": m.peak_area_px, "label": m.label,
         "frame_id": m.header.frame_id, "stamp": stamp_ns(m.header)}), 100)
    sub(ContactClip, ns + "/contact_clip", lambda m: got["clips"].append(
        {"id": m.episode_id, "label": m.label, "frames": len(m.frames), "peak_index": m.peak_index,
         "frame_ids": sorted({f.header.frame_id for f in m.frames}),
         "background": [m.background.width, m.background.height]}), 100)
    sub(TactileProperties, ns + "/tactile_properties", lambda m: got["properties"].append(
        {"label": m.label, "episode": m.episode_id, "hardness": m.hardness,
         "roughness": m.roughness, "texture": m.texture, "model_id": m.model_id,
         "frame_id": m.header.frame_id, "stamp": stamp_ns(m.header)}), 100)
    sub(PropertyComparison, ns + "/property_comparison", lambda m: got["comparisons"].append(
        {"property": m.property, "label_a": m.label_a, "label_b": m.label_b, "winner": m.winner,
         "sentence": m.sentence, "confidence": m.confidence, "stamp": stamp_ns(m.header)}), 100)
    # Transient-local like the inference node's publisher: latents sent before we matched count.
    latched = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    sub(TactileLatent, ns + "/tactile_latent", lambda m: got["latents"].append(
        {"source": m.source, "shape": list(m.shape), "n": len(m.data), "valid": m.valid,
         "solver": m.solver, "steps": m.steps, "guidance": m.guidance, "object": m.object,
         "condition_sources": list(m.condition_sources), "condition_age_s": list(m.condition_age_s),
         "finite": bool(np.all(np.isfinite(np.asarray(m.data, dtype=np.float32)))),
         "stamp": stamp_ns(m.header)}), latched)
    sub(DiagnosticArray, "/diagnostics", lambda m: got["diag"].extend(
        {"name": s.name, "level": int.from_bytes(s.level, "little") if isinstance(s.level, bytes) else int(s.level),
         "message": s.message, "stamp": stamp_ns(m.header), "t": time.monotonic() - t0,
         "values": {kv.key: kv.value for kv in s.values}} for s in m.status), 100)
    sub(Clock, "/clock", lambda m: got["clock"].append(m.clock.sec * 10**9 + m.clock.nanosec), 100)
    return got


def images(ns, n, faults=None):
    """`faults`: {"negative_sec": [k...], "big_nanosec": [k...], "bad_encoding": [k...]}: those
    images get an invalid stamp or an encoding no node takes."""
    faults = faults or {}
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
        if k in faults.get("negative_sec", []):
            m.header.stamp.sec = -1
        if k in faults.get("big_nanosec", []):
            m.header.stamp.nanosec = 2_000_000_000
        if k in faults.get("bad_encoding", []):
            m.encoding = "32FC1"
        m.data = np.clip(img, 0, 255).astype(np.uint8).tobytes()
        pub.publish(m)
        end = time.monotonic() + 0.04  # 25 fps
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.005)
    end = time.monotonic() + 2.5
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    print(json.dumps(summary(got)))
    return 0


def summary(got):
    got = dict(got)
    got["image_frames"] = sorted(got["image_frames"])
    got.pop("t0", None)
    return got


def listen(ns, seconds, until, stop_pid=0, stop_after=0, stop_seconds=0.0,
           wait_for=("/contact_state", "/contact_episode"), compressed=False, visual=None):
    """Collect until every count in `until` (e.g. {"episodes": 2}) is reached (then 0.5 s more)
    or `seconds` passed. With stop_pid: after `stop_after` images, SIGSTOP that process for
    `stop_seconds` (a stalled subscriber), then SIGCONT; the window goes into the summary."""
    node = Node("unitac_listen_peer")
    got = collect(node, ns)
    # Subscribe to images (which the sensor node waits for) only once the publishers of
    # `wait_for` (the contact node's, by default) are discovered, so nothing is published before
    # we can receive it.
    ready = time.monotonic() + seconds / 2
    while time.monotonic() < ready and not all(node.count_publishers(ns + t) > 0 for t in wait_for):
        rclpy.spin_once(node, timeout_sec=0.05)

    def on_image(m):
        got["images"] += 1
        got["image_frames"].add(m.header.frame_id)
        got["image_times"].append(round(time.monotonic() - got["t0"], 4))
    if compressed:
        node.create_subscription(CompressedImage, ns + "/image_raw/compressed", on_image, qos_profile_sensor_data)
    else:
        node.create_subscription(Image, ns + "/image_raw", on_image, qos_profile_sensor_data)
    if visual:
        cam = node.create_publisher(VisualObservation, ns + "/visual_observation", 10)

        def tick():
            m = VisualObservation()
            m.header.stamp = node.get_clock().now().to_msg()
            m.header.frame_id = "camera"
            m.names, m.values = list(visual["names"]), [float(v) for v in visual["values"]]
            cam.publish(m)
        node.create_timer(0.2, tick)
    end = time.monotonic() + seconds
    stopped = None
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.02)
        if stop_pid and stopped is None and got["images"] >= stop_after:
            os.kill(stop_pid, signal.SIGSTOP)
            stopped = time.monotonic()
            got["stop_window"] = [stopped - got["t0"], None]
        if stopped and got["stop_window"][1] is None and time.monotonic() - stopped >= stop_seconds:
            os.kill(stop_pid, signal.SIGCONT)
            got["stop_window"][1] = time.monotonic() - got["t0"]
            end = max(end, time.monotonic() + 3.0)
        if until and all(len(got[k]) >= v for k, v in until.items()) and (not stop_pid or stopped):
            end = min(end, time.monotonic() + 0.5)
    got["topics"] = {name: types for name, types in node.get_topic_names_and_types()
                     if name.startswith(ns + "/") or name == "/clock"}
    if stopped and got["stop_window"][1] is None:
        os.kill(stop_pid, signal.SIGCONT)
    print(json.dumps(summary(got)))
    return 0


def slow(ns, seconds, delay):
    """A slow reliable image subscriber: `delay` seconds of work per image."""
    node = Node("unitac_slow_peer")
    n = [0]

    def on_image(m):
        n[0] += 1
        time.sleep(delay)
    node.create_subscription(Image, ns + "/image_raw", on_image, 10)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    print(json.dumps({"images": n[0]}))
    return 0


def main():
    rclpy.init()
    try:
        if sys.argv[1] == "images":
            faults = json.loads(sys.argv[4]) if len(sys.argv) > 4 else {}
            return images(sys.argv[2], int(sys.argv[3]), faults)
        if sys.argv[1] == "slow":
            return slow(sys.argv[2], float(sys.argv[3]), float(sys.argv[4]))
        opts = json.loads(sys.argv[4]) if len(sys.argv) > 4 else {}
        return listen(sys.argv[2], float(sys.argv[3]), opts.get("until", {}),
                      opts.get("stop_pid", 0), opts.get("stop_after", 0), opts.get("stop_seconds", 0.0),
                      opts.get("wait_for", ("/contact_state", "/contact_episode")),
                      opts.get("compressed", False), opts.get("visual"))
    finally:
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
