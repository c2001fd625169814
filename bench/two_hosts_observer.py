"""rclpy observer for scripts/bench-two-hosts (a benchmark, not a test).

  two_hosts_observer.py SECONDS NS [NS ...]
      for SECONDS, record in each namespace NS the wall time each contact_episode and each
      property_comparison arrives; print one JSON object: per comparison, the time from the
      arrival of the episode that completed its pair (the release of the second touch) to the
      comparison's arrival [ms]; per episode, from its arrival to the arrival of its
      tactile_properties (the k-th properties answer the k-th episode of the namespace) [ms];
      counts of episodes, properties and comparisons per namespace.
"""
import json
import sys
import time

import rclpy
from rclpy.node import Node
from unitac_msgs.msg import ContactEpisode, PropertyComparison, TactileProperties


def main():
    seconds, namespaces = float(sys.argv[1]), sys.argv[2:]
    rclpy.init()
    try:
        node = Node("unitac_two_hosts_observer")
        last_episode = {ns: None for ns in namespaces}
        episodes = {ns: [] for ns in namespaces}
        counts = {ns: {"episodes": 0, "properties": 0, "comparisons": 0} for ns in namespaces}
        latencies, property_latencies = [], []

        def on_episode(ns):
            def cb(_m):
                last_episode[ns] = time.monotonic()
                episodes[ns].append(last_episode[ns])
                counts[ns]["episodes"] += 1
            return cb

        def on_properties(ns):
            def cb(_m):
                k = counts[ns]["properties"]
                counts[ns]["properties"] += 1
                if k < len(episodes[ns]):
                    property_latencies.append(
                        round(time.monotonic() - episodes[ns][k], 6))
            return cb

        def on_comparison(ns):
            def cb(_m):
                counts[ns]["comparisons"] += 1
                if last_episode[ns] is not None:
                    latencies.append(round(time.monotonic() - last_episode[ns], 6))
            return cb

        for ns in namespaces:
            node.create_subscription(ContactEpisode, f"{ns}/contact_episode", on_episode(ns), 10)
            node.create_subscription(PropertyComparison, f"{ns}/property_comparison",
                                     on_comparison(ns), 10)
            node.create_subscription(TactileProperties, f"{ns}/tactile_properties",
                                     on_properties(ns), 10)
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.01)
        print(json.dumps({"latencies_s": latencies, "property_latencies_s": property_latencies,
                          "counts": counts}))
        return 0
    finally:
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
