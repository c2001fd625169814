# shellcheck shell=bash
# stop_all PID...: SIGINT, up to 5 s to exit cleanly, then SIGKILL and reap. For benchmark
# scripts that start ROS nodes: a Fast DDS participant can hang in its teardown (seen once: a
# contact node spinning in DomainParticipant::set_listener after SIGINT).
stop_all() {
  local p alive
  for p in "$@"; do kill -INT "$p" 2>/dev/null || true; done
  for _ in $(seq 50); do
    alive=0
    for p in "$@"; do kill -0 "$p" 2>/dev/null && alive=1; done
    [ "$alive" = 1 ] || break
    sleep 0.1
  done
  for p in "$@"; do kill -KILL "$p" 2>/dev/null || true; wait "$p" 2>/dev/null || true; done
}
