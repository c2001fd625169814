"""rclpy stand-in for a ros2_control gripper controller: a control_msgs/action/GripperCommand
server with the documented semantics of ros2_controllers' GripperActionController
(gripper_controllers/include/gripper_controllers/gripper_action_controller_impl.hpp, Jazzy):

- every goal is accepted; a new goal preempts the active one, which ends canceled;
- a cancel request holds the current position and ends the goal canceled;
- success when |goal - position| < goal_tolerance (0.01 m): result reached_goal;
- stall when |velocity| <= stall_velocity_threshold (0.001 m/s) for stall_timeout (1 s) short of
  the goal: result stalled; succeeded with allow_stalling, else aborted;
- feedback (position, effort, stalled, reached_goal) at action_monitor_rate (20 Hz).
The fingers move at the controller's speed (the goal has none): --speed, default 0.02 m/s, the
slowest a Robotiq 2F-85 moves (datasheet: 20-150 mm/s).

  gripper_action_server.py NS ACTION SECONDS MODE [--allow-stalling] [--speed V]

MODE forward: the gripper is the sim node's (crates/ros sim node with gripper_commands:=held):
  each goal becomes a unitac_msgs/GripperCommand setpoint (POSITION, the speed above, force =
  max_effort) on NS/controller/gripper_setpoint; the state comes from NS/gripper_status, on sim time.
MODE own: a gripper simulated here on its own sim time (10 ms steps, paced at real time): /clock,
  NS/joint_states (joint gripper_finger_opening: opening, effort = force) and a camera's
  NS/visual_observation (a 70 mm cup at x 0.45 m, y 0) every step; the fingers stop on the cup
  (70 mm) and squeeze with max_effort. It records NS/policy_status, and follows NS/arm_pose
  (geometry_msgs/PoseStamped) as a Cartesian controller would: it records each target's frame
  and position.

stdin, one line each (answers on stdout). Both act on the client's latest goal: from the command
on, every goal the client sends is kept executing (a goal within tolerance of the fingers would
otherwise end at once, before the fault could reach it), and the fault goes to the latest once
one has come and the goals already on their way have landed; "no goal" if the client sent none
within 20 s:
  "abort"    abort it (a controller fault, stalled false): "aborted T_NS"
  "preempt"  a second client sends a goal (hold where the fingers are; its max_effort
             OTHER_EFFORT tells it apart), preempting it: "preempted T_NS"
  own mode: the clock stops when that goal is accepted (T_NS: the last published sim time) until
  "resume" (the caller has seen the client hear of the goal's end; at most 30 s), then goes on.
  "end"      print a JSON summary and exit
out: "ready" once the server is up; "goal P E" for each accepted goal.
"""
import json
import sys
import threading
import time

import rclpy
from control_msgs.action import GripperCommand as GripperAction
from geometry_msgs.msg import PoseStamped
from rclpy.action import ActionClient, ActionServer, CancelResponse, GoalResponse
from rclpy.executors import MultiThreadedExecutor
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from unitac_msgs.msg import GripperCommand, GripperStatus, PolicyStatus, VisualObservation

GOAL_TOLERANCE = 0.01
STALL_VELOCITY = 0.001
STALL_TIMEOUT_S = 1.0
MONITOR_PERIOD_S = 0.05
STEP_NS = 10_000_000
CUP_M = 0.07
MAX_OPENING_M = 0.11
# The second client's goal effort [N]: no policy sends it, so the server knows that goal.
OTHER_EFFORT = 10.0123
# How long the goals already on their way get to land once the clock stopped [s].
LAND_S = 0.1


def stamp_ns(t):
    return t.sec * 10**9 + t.nanosec


def to_time(ns):
    from builtin_interfaces.msg import Time
    return Time(sec=ns // 10**9, nanosec=ns % 10**9)


def main():
    ns, action, seconds, mode = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4]
    allow_stalling = "--allow-stalling" in sys.argv
    speed = float(sys.argv[sys.argv.index("--speed") + 1]) if "--speed" in sys.argv else 0.02
    rclpy.init()
    node = rclpy.create_node("gripper_action_controller")
    lock = threading.Lock()
    say_lock = threading.Lock()

    def say(line):
        with say_lock:
            sys.stdout.write(line + "\n")
            sys.stdout.flush()

    # The gripper as the controller sees it: sim time, position, effort, and when it last moved.
    state = {"t_ns": 0, "position": None, "effort": 0.0, "last_moved_ns": 0,
             "target": None, "max_effort": 0.0}
    # The active goal: {"gh", "flag": None | "held" | "preempted" | "aborted"}; "held": kept
    # executing until a fault ends it. "hold": the client's goals are held.
    active = {"goal": None, "hold": False}
    record = {"goals": [], "ends": [], "status": [], "poses": []}
    qos = QoSProfile(depth=100)

    def on_state(t_ns, position, effort):
        with lock:
            p = state["position"]
            if p is None or abs(position - p) > STALL_VELOCITY * max(t_ns - state["t_ns"], 1) * 1e-9:
                state["last_moved_ns"] = t_ns
            state.update(t_ns=t_ns, position=position, effort=effort)

    setpoint_pub = None
    if mode == "forward":
        setpoint_pub = node.create_publisher(GripperCommand, ns + "/controller/gripper_setpoint",
                                             qos)
        node.create_subscription(
            GripperStatus, ns + "/gripper_status",
            lambda m: on_state(stamp_ns(m.header.stamp), m.opening_m, m.force_n), qos)

    def command(position, max_effort):
        with lock:
            state["target"], state["max_effort"] = position, max_effort
            state["last_moved_ns"] = state["t_ns"]
        if setpoint_pub is not None:
            m = GripperCommand()
            m.header.stamp = to_time(state["t_ns"])
            m.mode = GripperCommand.MODE_POSITION
            m.position_m, m.speed_m_s, m.force_n = position, speed, max_effort
            m.reason = "gripper action controller"
            setpoint_pub.publish(m)

    def goal_cb(_goal):
        return GoalResponse.ACCEPT

    def cancel_cb(_gh):
        return CancelResponse.ACCEPT

    def accepted_cb(gh):
        with lock:
            old = active["goal"]
            if old is not None and old["flag"] in (None, "held"):
                old["flag"] = "preempted"
            other = gh.request.command.max_effort == OTHER_EFFORT
            flag = "held" if active["hold"] and not other else None
            if other:
                active["hold"] = False
            active["goal"] = {"gh": gh, "flag": flag}
            if flag == "held" and mode == "own":
                paused.set()
        c = gh.request.command
        record["goals"].append([c.position, c.max_effort])
        command(c.position, c.max_effort)
        say(f"goal {c.position} {c.max_effort}")
        gh.execute()

    def result(position, effort, stalled, reached):
        r = GripperAction.Result()
        r.position, r.effort, r.stalled, r.reached_goal = position, effort, stalled, reached
        return r

    def end_canceled(gh):
        # A preempted or cancelled goal ends canceled, as the controller's setCanceled does.
        from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
        if not gh.is_cancel_requested:
            gh._update_state(_rclpy.GoalEvent.CANCEL_GOAL)
        gh.canceled()

    def execute_cb(gh):
        me = None
        with lock:
            if active["goal"] is not None and active["goal"]["gh"] is gh:
                me = active["goal"]
        while rclpy.ok():
            time.sleep(0.002)
            with lock:
                flag = me["flag"] if me else "preempted"
                pos, eff = state["position"], state["effort"]
                t, moved = state["t_ns"], state["last_moved_ns"]
            pos = pos if pos is not None else float("nan")
            if flag == "preempted" or gh.is_cancel_requested:
                if gh.is_cancel_requested and flag is None:
                    command(pos, state["max_effort"])  # hold the current position
                end_canceled(gh)
                record["ends"].append(["canceled", t])
                return result(pos, eff, False, False)
            if flag == "aborted":
                gh.abort()
                record["ends"].append(["aborted", t])
                return result(pos, eff, False, False)
            if flag == "held":
                continue
            target = gh.request.command.position
            if abs(target - pos) < GOAL_TOLERANCE:
                gh.succeed()
                with lock:
                    active["goal"] = None if active["goal"] is me else active["goal"]
                record["ends"].append(["reached", t])
                return result(pos, eff, False, True)
            if t - moved > STALL_TIMEOUT_S * 1e9:
                with lock:
                    active["goal"] = None if active["goal"] is me else active["goal"]
                if allow_stalling:
                    gh.succeed()
                else:
                    gh.abort()
                record["ends"].append(["stalled", t])
                return result(pos, eff, True, False)
            now = time.monotonic()
            if now - me.setdefault("fed", 0.0) >= MONITOR_PERIOD_S:
                me["fed"] = now
                fb = GripperAction.Feedback()
                fb.position, fb.effort, fb.stalled, fb.reached_goal = pos, eff, False, False
                gh.publish_feedback(fb)
        return result(float("nan"), 0.0, False, False)

    ActionServer(node, GripperAction, action if action.startswith("/") else f"{ns}/{action}",
                 execute_callback=execute_cb, goal_callback=goal_cb, cancel_callback=cancel_cb,
                 handle_accepted_callback=accepted_cb)
    other = ActionClient(node, GripperAction, action if action.startswith("/") else f"{ns}/{action}")

    paused = threading.Event()
    resumed = threading.Event()

    def simulate():
        """Own mode: the gripper, its joint states, the camera and /clock, every 10 ms."""
        clock_pub = node.create_publisher(Clock, "/clock", 10)
        joint_pub = node.create_publisher(JointState, ns + "/joint_states", qos)
        visual_pub = node.create_publisher(VisualObservation, ns + "/visual_observation", qos)
        node.create_subscription(
            PolicyStatus, ns + "/policy_status",
            lambda m: record["status"].append({"stamp": stamp_ns(m.header.stamp), "phase": m.phase,
                                               "safety_ok": m.safety_ok, "message": m.message}),
            qos)
        node.create_subscription(
            PoseStamped, ns + "/arm_pose",
            lambda m: record["poses"].append({
                "stamp": stamp_ns(m.header.stamp), "frame_id": m.header.frame_id,
                "position": [m.pose.position.x, m.pose.position.y, m.pose.position.z],
                "orientation": [m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z,
                                m.pose.orientation.w]}),
            qos)
        opening, t = 0.085, 0
        t0 = time.monotonic()
        while rclpy.ok():
            while paused.is_set():
                time.sleep(0.01)
                t0 = time.monotonic() - t * 1e-9
            time.sleep(max(0.0, t0 + t * 1e-9 - time.monotonic()))
            t += STEP_NS
            with lock:
                target, max_effort = state["target"], state["max_effort"]
            target = opening if target is None else min(max(target, 0.0), MAX_OPENING_M)
            step = speed * STEP_NS * 1e-9
            new = opening + max(-step, min(step, target - opening))
            effort = 0.0
            if new <= CUP_M <= opening or (opening <= CUP_M and new < opening):
                new, effort = max(new, CUP_M), (max_effort if target < CUP_M else 0.0)
            opening = new
            on_state(t, opening, effort)
            clock_pub.publish(Clock(clock=to_time(t)))
            v = VisualObservation()
            v.header.stamp, v.header.frame_id = to_time(t), "table"
            v.names, v.values = ["cup_x_m", "cup_y_m", "cup_width_m"], [0.45, 0.0, CUP_M]
            visual_pub.publish(v)
            js = JointState()
            js.header.stamp = to_time(t)
            js.name, js.position, js.effort = ["gripper_finger_opening"], [opening], [effort]
            joint_pub.publish(js)

    def after_fault(what):
        if mode == "own":
            paused.set()
        with lock:
            t = state["t_ns"]
        say(f"{what} {t}")
        if mode == "own":
            def resume():
                resumed.wait(30)
                resumed.clear()
                paused.clear()
            threading.Thread(target=resume, daemon=True).start()

    def hold_goals():
        """Hold the client's goals from now on (own mode: the clock stops at the first) and wait
        for one, then for those already on their way; False if none came within 20 s."""
        with lock:
            active["hold"] = True
        t0 = time.monotonic()
        while time.monotonic() - t0 < 20:
            with lock:
                g = active["goal"]
                held = g is not None and g["flag"] == "held"
            if held:
                time.sleep(LAND_S)
                return True
            time.sleep(0.002)
        with lock:
            active["hold"] = False
        return False

    def read_stdin():
        for line in sys.stdin:
            cmd = line.strip()
            if cmd == "abort":
                if not hold_goals():
                    say("no goal")
                    continue
                with lock:
                    active["goal"]["flag"] = "aborted"
                    active["hold"] = False
                after_fault("aborted")
            elif cmd == "preempt":
                if not hold_goals():
                    say("no goal")
                    continue
                goal = GripperAction.Goal()
                with lock:
                    goal.command.position = state["position"] or 0.0
                goal.command.max_effort = OTHER_EFFORT
                other.send_goal_async(goal)
                time.sleep(0.05)
                after_fault("preempted")
            elif cmd == "resume":
                resumed.set()
            elif cmd == "end":
                break
        done.set()

    done = threading.Event()
    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(node)
    threading.Thread(target=executor.spin, daemon=True).start()
    if mode == "own":
        threading.Thread(target=simulate, daemon=True).start()
    threading.Thread(target=read_stdin, daemon=True).start()
    say("ready")
    done.wait(timeout=seconds)
    say(json.dumps(record))
    executor.shutdown(timeout_sec=1.0)
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
