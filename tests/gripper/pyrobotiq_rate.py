"""Status round trips per second of pyRobotiqGripper against a gripper (or a simulated one).

Usage: pyrobotiq_rate.py PORT [SECONDS]
Connects, then calls readStatus() (FC 0x04, three registers at 0x07D0: the same request as
`unitac gripper ... bench` without --allow-motion) back to back for SECONDS (default 5) and prints
one JSON line: {"client", "version", "reads", "seconds", "rate_hz", "p50_s", "p99_s"}. Reads
only: the gripper does not move.
"""

import json
import sys
import time
from importlib.metadata import version

import pyrobotiqgripper as rq


def main() -> int:
    port = sys.argv[1]
    seconds = float(sys.argv[2]) if len(sys.argv) > 2 else 5.0
    g = rq.RobotiqGripper(com_port=port, device_id=9)
    rtt = []
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        t = time.perf_counter()
        g.readStatus(raiseOnFault=False)
        rtt.append(time.perf_counter() - t)
    total = time.perf_counter() - t0
    g.disconnect()
    rtt.sort()

    def pick(q):
        return rtt[min(len(rtt) - 1, round(q * (len(rtt) - 1)))]

    print(json.dumps({
        "client": "pyrobotiqgripper",
        "version": version("pyrobotiqgripper"),
        "reads": len(rtt),
        "seconds": round(total, 3),
        "rate_hz": round(len(rtt) / total, 1),
        "p50_s": round(pick(0.5), 6),
        "p99_s": round(pick(0.99), 6),
    }))
    return 0


if __name__ == "__main__":
    sys.exit(main())
