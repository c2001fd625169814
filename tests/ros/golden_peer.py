"""rclpy observer for the golden-output test (crates/ros/tests/golden.rs).

  golden_peer.py NS SECONDS UNTIL_JSON
      subscribe (reliable, keep all, transient-local where the publisher latches) to the stage
      outputs in NS: contact_state, contact_episode, tactile_properties, property_comparison,
      tactile_latent; once the contact node's publishers are discovered, print "ready" on stderr;
      collect until every count in UNTIL_JSON (e.g. {"contact_episode": 2}) arrived and then 1 s
      passed with nothing new, or SECONDS passed. Print one JSON line per message on stdout:
      {"topic": name, "cdr": hex of the serialized message}, in arrival order per topic; then
      {"topic": "contact_dropped", "value": N}: the largest `dropped` count the contact node in
      NS reported on /diagnostics (frames it lost on the way, from stamp gaps).

The CDR bytes are decoded by the project's own codecs on the Rust side, so the comparison with
the golden files covers the ROS serialization too.
"""
import json
import sys
import time

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile
from rclpy.serialization import serialize_message
from diagnostic_msgs.msg import DiagnosticArray
from unitac_msgs.msg import (ContactEpisode, ContactState, PropertyComparison, TactileLatent,
                             TactileProperties)

TOPICS = {"contact_state": ContactState, "contact_episode": ContactEpisode,
          "tactile_properties": TactileProperties, "property_comparison": PropertyComparison,
          "tactile_latent": TactileLatent}


def main():
    ns, seconds, until = sys.argv[1], float(sys.argv[2]), json.loads(sys.argv[3])
    rclpy.init()
    try:
        node = Node("unitac_golden_peer")
        got = {t: [] for t in TOPICS}
        last = [time.monotonic()]

        def keep(topic):
            def cb(m):
                got[topic].append(serialize_message(m).hex())
                last[0] = time.monotonic()
            return cb

        for topic, ty in TOPICS.items():
            latched = topic == "tactile_latent"
            qos = QoSProfile(history=HistoryPolicy.KEEP_ALL,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL if latched
                             else DurabilityPolicy.VOLATILE)
            node.create_subscription(ty, f"{ns}/{topic}", keep(topic), qos)
        dropped = [0]

        def diagnostics(m):
            for st in m.status:
                if st.name.startswith("unitac_contact") and ns in st.name:
                    for kv in st.values:
                        if kv.key == "dropped":
                            dropped[0] = max(dropped[0], int(kv.value))

        node.create_subscription(DiagnosticArray, "/diagnostics", diagnostics, 100)
        end = time.monotonic() + seconds
        ready = False
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.02)
            if not ready and node.count_publishers(f"{ns}/contact_state") > 0:
                ready = True
                print("ready", file=sys.stderr, flush=True)
            done = all(len(got[k]) >= v for k, v in until.items())
            if done and time.monotonic() - last[0] > 1.0:
                break
        for topic, msgs in got.items():
            for m in msgs:
                print(json.dumps({"topic": topic, "cdr": m}))
        print(json.dumps({"topic": "contact_dropped", "value": dropped[0]}))
        return 0
    finally:
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
