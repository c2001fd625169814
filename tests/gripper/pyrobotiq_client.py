"""A real Robotiq client against a (simulated) 2F-85: pyRobotiqGripper, as users drive one.

Usage: pyrobotiq_client.py PORT
Runs activate, move, open, close (on the object the test put between the fingers), status and
object detection, re-activation, and prints one JSON line per step: {"step", "status" (the
gripper's registers as pyRobotiqGripper decodes them), ...}. Exit 0 when every call returned;
the Rust test (crates/gripper/tests/pyrobotiq.rs) judges the values.
"""

import json
import sys
import time

import pyrobotiqgripper as rq


def main() -> int:
    port = sys.argv[1]
    g = rq.RobotiqGripper(com_port=port, device_id=9)

    def report(step, **extra):
        st = {k: int(v) for k, v in g.status().items() if k != "time"}
        print(json.dumps({"step": step, "status": st, **extra}), flush=True)

    report("connected")
    g.activate()
    report("activated", activated=bool(g.isActivated()))
    g.move(100)
    report("move", position=g.position())
    g.open()
    report("open", position=g.position(), object=int(g.objectDetection()))
    # Close with a low force: the simulated object stops the fingers.
    t0 = time.monotonic()
    g.close(speed=255, force=0)
    report("close", position=g.position(), object=int(g.objectDetection()),
           seconds=round(time.monotonic() - t0, 3))
    g.open()
    report("open_again", position=g.position(), object=int(g.objectDetection()))
    # Re-activation (reset, then rACT rising edge): no detection left from before.
    g.close(speed=255, force=0)
    g.activate()
    report("reactivated", activated=bool(g.isActivated()), object=int(g.objectDetection()))
    g.disconnect()
    return 0


if __name__ == "__main__":
    sys.exit(main())
