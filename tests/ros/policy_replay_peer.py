"""rclpy peer of the policy golden test (crates/ros/tests/policy_golden.rs).

  policy_replay_peer.py NS INPUTS_JSONL

INPUTS_JSONL: one {"topic": "visual_observation" | "gripper_status", "cdr": hex} per line, the
policy stage's inputs in the order the embedded trial fed them. Once the policy node in NS
subscribes to both topics (and 1 s more for discovery both ways), each line is published on
NS/<topic> (reliable); after any other input it waits 30 ms, and after a gripper_status (the
policy's tick) for the PolicyStatus stamped like it (10 s at most) before the next line, so
every input of a tick is there before the tick, as in the chain. Then it prints one JSON line per message the node published on
gripper_command, arm_command and policy_status: {"topic": name, "cdr": hex}, in arrival order
per topic, and {"topic": "missed", "value": N} (ticks answered by nothing within 10 s).
"""
import json
import sys
import time

import rclpy
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile
from rclpy.serialization import deserialize_message, serialize_message
from unitac_msgs.msg import ArmCommand, GripperCommand, GripperStatus, PolicyStatus, VisualObservation

INPUTS = {"visual_observation": VisualObservation, "gripper_status": GripperStatus}
OUTPUTS = {"gripper_command": GripperCommand, "arm_command": ArmCommand,
           "policy_status": PolicyStatus}


def stamp_ns(header):
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def spin_until(node, done, seconds):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if done():
            return True
        rclpy.spin_once(node, timeout_sec=0.005)
    return done()


def main():
    ns, path = sys.argv[1], sys.argv[2]
    lines = [json.loads(l) for l in open(path) if l.strip()]
    rclpy.init()
    try:
        node = Node("unitac_policy_replay_peer")
        qos = QoSProfile(history=HistoryPolicy.KEEP_ALL)
        pubs = {t: node.create_publisher(ty, f"{ns}/{t}", qos) for t, ty in INPUTS.items()}
        got = {t: [] for t in OUTPUTS}
        ticks = set()

        def keep(topic):
            def cb(m):
                got[topic].append(serialize_message(m).hex())
                if topic == "policy_status":
                    ticks.add(stamp_ns(m.header))
            return cb

        for t, ty in OUTPUTS.items():
            node.create_subscription(ty, f"{ns}/{t}", keep(t), qos)
        subscribed = lambda: all(p.get_subscription_count() > 0 for p in pubs.values())
        if not spin_until(node, subscribed, 60):
            print("the policy node did not subscribe", file=sys.stderr)
            return 2
        spin_until(node, lambda: False, 1.0)
        missed = 0
        for l in lines:
            ty = INPUTS[l["topic"]]
            m = deserialize_message(bytes.fromhex(l["cdr"]), ty)
            pubs[l["topic"]].publish(m)
            if l["topic"] == "gripper_status":
                t = stamp_ns(m.header)
                if not spin_until(node, lambda: t in ticks, 10):
                    missed += 1
            else:
                # Another topic than the tick's: give it time to reach the node first (the
                # order of messages on two topics is not given).
                spin_until(node, lambda: False, 0.03)
        # The last tick's commands may come just after its status.
        spin_until(node, lambda: False, 0.5)
        for topic, msgs in got.items():
            for m in msgs:
                print(json.dumps({"topic": topic, "cdr": m}))
        print(json.dumps({"topic": "missed", "value": missed}))
        return 0
    finally:
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
