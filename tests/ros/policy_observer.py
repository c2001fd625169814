"""rclpy observer of the closed loop over ROS (crates/ros/tests/policy_loop.rs).

  policy_observer.py NS SECONDS

Records NS/policy_status, NS/gripper_command, /clock, NS/sim/outcome, NS/contact_state (stamp and
in_contact), NS/tactile_latent (stamps, transient-local like the policy's subscription),
NS/contact_episode (end stamps: each episode's clip goes to the inference node) and
NS/gripper_status (stamps: the policy's ticks as sent); counts NS/gripper_status and NS/image_raw,
so the sim's wait for subscribers waits for it as well. Talks to the test on stdin/stdout, one
line each:
  out: "ready"             once the policy node's PolicyStatus and ArmCommand publishers
                           are matched (start the sim after this)
  out: "phase NAME T_NS"   the first PolicyStatus of each phase (T_NS its stamp)
  in:  "mark"              record the latest PolicyStatus stamp as the mark (the test froze the
                           sim and killed a producer: the last tick before), answer
                           "marked T_NS"
  in:  "publishers TOPIC N"  wait until the graph shows N publishers on NS/TOPIC (a producer's host
                           went away or came back), answer "publishers TOPIC N"
  in:  "subscribers TOPIC N" the same for subscriptions (a restarted consumer is listening),
                           answer "subscribers TOPIC N"
  in:  "holds N"           answer "held T_NS" once N PolicyStatus after the mark were holds
                           (safety_ok false), T_NS the N-th's stamp
  out: "outcome"           the sim's outcome arrived
  in:  "joint_states N"    publish N sensor_msgs/JointState on NS/joint_states at 30 Hz (system
                           time stamps, opening 0.07 m, effort 1.5 N), then stop; answer
                           "published T_NS" with the last stamp
  in:  "pause 1" | "pause 0"  publish std_msgs/Bool on NS/sim/pause (the sim holds sim time
                           between steps, spinning on); answer "paused T_NS" once /clock has
                           not moved for 0.5 s (T_NS the last), or "resumed"
  in:  "end"               (or SECONDS passed, or stdin closed) print the summary as one JSON line
                           and exit
"""
import json
import sys
import threading
import time

import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Image, JointState
from std_msgs.msg import Bool, String
from unitac_msgs.msg import (ContactEpisode, ContactState, GripperCommand, GripperStatus,
                             PolicyStatus, TactileLatent)


def stamp_ns(t):
    return t.sec * 10**9 + t.nanosec


def main():
    ns, seconds = sys.argv[1], float(sys.argv[2])
    rclpy.init()
    node = rclpy.create_node("policy_observer")
    lock = threading.Lock()
    got = {"status": [], "commands": [], "outcome": None, "mark_ns": None, "clock_ns": 0,
           "clocks": 0, "contact": [], "latents": [],
           "episodes": [], "gripper_stamps": []}
    holds = {"want": None}
    phases = set()

    def say(line):
        sys.stdout.write(line + "\n")
        sys.stdout.flush()

    def on_status(m):
        t = stamp_ns(m.header.stamp)
        with lock:
            got["status"].append({"stamp": t, "phase": m.phase, "safety_ok": m.safety_ok,
                                  "message": m.message, "mode": m.mode, "scene": m.scene})
            new = m.phase not in phases
            phases.add(m.phase)
        if new:
            say(f"phase {m.phase} {t}")
        with lock:
            want, mark = holds["want"], got["mark_ns"] or 0
            held = [s for s in got["status"] if s["stamp"] > mark and not s["safety_ok"]]
            if want is not None and len(held) >= want:
                holds["want"] = None
                say(f"held {held[want - 1]['stamp']}")

    def on_command(m):
        with lock:
            got["commands"].append({"stamp": stamp_ns(m.header.stamp), "mode": m.mode,
                                    "position_m": m.position_m, "force_n": m.force_n,
                                    "reason": m.reason})

    def on_clock(m):
        with lock:
            got["clock_ns"] = max(got["clock_ns"], stamp_ns(m.clock))
            got["clocks"] += 1

    def on_outcome(m):
        with lock:
            first = got["outcome"] is None
            got["outcome"] = json.loads(m.data)
        if first:
            say("outcome")

    def on_contact(m):
        with lock:
            got["contact"].append({"stamp": stamp_ns(m.header.stamp),
                                   "in_contact": m.in_contact})

    def on_latent(m):
        with lock:
            got["latents"].append(stamp_ns(m.header.stamp))

    def on_episode(m):
        with lock:
            got["episodes"].append(stamp_ns(m.header.stamp))

    reliable = QoSProfile(depth=100)
    node.create_subscription(PolicyStatus, ns + "/policy_status", on_status, reliable)
    node.create_subscription(GripperCommand, ns + "/gripper_command", on_command, reliable)
    node.create_subscription(Clock, "/clock", on_clock, 10)
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    node.create_subscription(String, ns + "/sim/outcome", on_outcome, latched)
    node.create_subscription(ContactState, ns + "/contact_state", on_contact, reliable)
    node.create_subscription(ContactEpisode, ns + "/contact_episode", on_episode, reliable)
    node.create_subscription(TactileLatent, ns + "/tactile_latent", on_latent,
                             QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL))

    counts = {"gripper_status": 0, "images": 0}

    def count(key):
        def cb(_m):
            with lock:
                counts[key] += 1
        return cb

    def on_gripper(m):
        with lock:
            counts["gripper_status"] += 1
            got["gripper_stamps"].append(stamp_ns(m.header.stamp))

    node.create_subscription(GripperStatus, ns + "/gripper_status", on_gripper, reliable)
    node.create_subscription(Image, ns + "/image_raw", count("images"), 10)
    got["counts"] = counts

    end = threading.Event()
    joint_pub = node.create_publisher(JointState, ns + "/joint_states", reliable)
    pause_pub = node.create_publisher(Bool, ns + "/sim/pause", QoSProfile(depth=10))

    def pause(on):
        pause_pub.publish(Bool(data=on))
        if not on:
            say("resumed")
            return
        # Held once sim time stands still (a step under way finishes first).
        last, since = None, time.monotonic()
        while True:
            time.sleep(0.05)
            with lock:
                now = got["clock_ns"]
            if now != last:
                last, since = now, time.monotonic()
            elif time.monotonic() - since >= 0.5:
                say(f"paused {now}")
                return

    def publish_joint_states(n):
        last = 0
        t0 = time.monotonic()
        for k in range(n):
            # On a fixed schedule (no drift): the k-th state at t0 + k / 30 s.
            time.sleep(max(0.0, t0 + k / 30.0 - time.monotonic()))
            m = JointState()
            m.header.stamp = node.get_clock().now().to_msg()
            m.name = ["gripper_finger_opening"]
            m.position = [0.07]
            m.effort = [1.5]
            joint_pub.publish(m)
            last = stamp_ns(m.header.stamp)
        say(f"published {last}")

    def read_stdin():
        for line in sys.stdin:
            cmd = line.strip()
            if cmd == "mark":
                # Let /clock messages already sent arrive before reading the latest.
                time.sleep(0.3)
                with lock:
                    got["mark_ns"] = max((s["stamp"] for s in got["status"]), default=0)
                say(f"marked {got['mark_ns']}")
            elif cmd.startswith("publishers ") or cmd.startswith("subscribers "):
                what, topic, n = cmd.split()
                wanted[0] = (what, topic, int(n))
            elif cmd.startswith("holds "):
                with lock:
                    holds["want"] = int(cmd.split()[1])
            elif cmd.startswith("joint_states "):
                threading.Thread(target=publish_joint_states, args=(int(cmd.split()[1]),),
                                 daemon=True).start()
            elif cmd in ("pause 1", "pause 0"):
                pause(cmd == "pause 1")
            elif cmd == "end":
                break
        end.set()

    # (publishers | subscribers, topic, count) the test waits for; checked on the spinning
    # thread, which owns the graph.
    wanted = [None]
    threading.Thread(target=read_stdin, daemon=True).start()
    t0 = time.monotonic()
    while time.monotonic() - t0 < seconds and not (
            node.count_publishers(ns + "/policy_status") > 0
            and node.count_publishers(ns + "/arm_command") > 0):
        rclpy.spin_once(node, timeout_sec=0.05)
    say("ready")
    while not end.is_set() and time.monotonic() - t0 < seconds:
        rclpy.spin_once(node, timeout_sec=0.02)
        w = wanted[0]
        count = node.count_publishers if w and w[0] == "publishers" else node.count_subscribers
        if w is not None and count(f"{ns}/{w[1]}") == w[2]:
            wanted[0] = None
            say(f"{w[0]} {w[1]} {w[2]}")
    with lock:
        say(json.dumps(got))
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
