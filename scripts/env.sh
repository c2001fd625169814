# Environment for building and running the workspace (sourced by scripts/run, scripts/test,
# scripts/unitac, scripts/unitac-lab and scripts/setup.sh; never needed by hand). Paths are
# derived from the repo root.
# The four ROS-from-PyPI workarounds live here and in setup.sh (../shared/notes/ros2-from-pypi.md).
#
# UNITAC_ROS selects the ROS 2 environment (both set up by scripts/setup.sh):
#   kilted (default)  the Kilted wheels in .venv, unitac_msgs in .build/msgs/install (control_msgs
#                     in .build/control_msgs/install), target/
#   jazzy             the Jazzy wheels in .venv-jazzy, unitac_msgs in .build/jazzy/msgs/install,
#                     and CARGO_TARGET_DIR=target/jazzy: r2r's generated bindings and everything
#                     linking them differ per distro, and r2r reuses cached bindings without
#                     re-emitting its cfg flags, so the two must never share a target dir.
# Sourcing again (also with another UNITAC_ROS) replaces what an earlier source set: the library
# and Python paths are rebuilt from the values before the first source (UNITAC_BASE_*).
_UNITAC_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
case "${UNITAC_ROS:-kilted}" in
  kilted)
    _V="$_UNITAC_ROOT/.venv"
    _B="$_UNITAC_ROOT/.build"
    # Leave a target dir chosen by the caller alone, but not Jazzy's from an earlier source.
    if [ "${CARGO_TARGET_DIR:-}" = "$_UNITAC_ROOT/target/jazzy" ]; then unset CARGO_TARGET_DIR; fi
    ;;
  jazzy)
    _V="$_UNITAC_ROOT/.venv-jazzy"
    _B="$_UNITAC_ROOT/.build/jazzy"
    export CARGO_TARGET_DIR="$_UNITAC_ROOT/target/jazzy"
    ;;
  *)
    echo "scripts/env.sh: UNITAC_ROS must be kilted or jazzy, not '${UNITAC_ROS}'" >&2
    return 2 2>/dev/null || exit 2
    ;;
esac
export UNITAC_ROS="${UNITAC_ROS:-kilted}"
_M="$_B/msgs/install"
# control_msgs as a robot with ros2_control has it installed (an underlay, not part of colcon's
# workspace: see msg/control_msgs/README.md).
_C="$_B/control_msgs/install"
_SITE="$_V/lib/python3.11/site-packages"
export UNITAC_ROOT="$_UNITAC_ROOT"
# The venv of the selected distro: rclpy peers, colcon.
export UNITAC_VENV="$_V"
# Generated model bundles (scripts/setup.sh step 5).
export UNITAC_MODELS="$_UNITAC_ROOT/.build/models"
# ONNX Runtime shared library from the pinned wheel in .venv (ort load-dynamic), for either distro.
export UNITAC_ORT_LIB="$_UNITAC_ROOT/.venv/lib/python3.11/site-packages/onnxruntime/capi/libonnxruntime.so.1.31.1"
# libpython for binaries that link r2r (workaround 3; crates/ros/build.rs reads this).
_PYLIBDIR="$("$_V/bin/python" -c 'import sysconfig; print(sysconfig.get_config_var("LIBDIR"))' 2>/dev/null || true)"
export UNITAC_PYTHON_LIBDIR="$_PYLIBDIR"
export AMENT_PREFIX_PATH="$_M:$_C:$_V"
# Workaround 2: librmw_implementation.so shim directory on CMAKE_PREFIX_PATH.
export CMAKE_PREFIX_PATH="$AMENT_PREFIX_PATH:$_B/ros-shim"
# Kilted, workaround 1: r2r 0.9.7 does not know "kilted"; the bindings still come from the Kilted
# headers. Jazzy: the real distro, which r2r supports by name.
export ROS_DISTRO=jazzy
# Library and Python paths: rebuilt from what the caller had before the first source.
export UNITAC_BASE_LD_LIBRARY_PATH="${UNITAC_BASE_LD_LIBRARY_PATH-${LD_LIBRARY_PATH:-}}"
export UNITAC_BASE_PYTHONPATH="${UNITAC_BASE_PYTHONPATH-${PYTHONPATH:-}}"
_LIBS="$_M/lib:$_C/lib:$_V/lib"
for _d in "$_SITE"/ros_*.libs "$_SITE"/numpy.libs; do [ -d "$_d" ] && _LIBS="$_LIBS:$_d"; done
[ -n "$_PYLIBDIR" ] && _LIBS="$_LIBS:$_PYLIBDIR"
export LD_LIBRARY_PATH="$_LIBS${UNITAC_BASE_LD_LIBRARY_PATH:+:$UNITAC_BASE_LD_LIBRARY_PATH}"
export PYTHONPATH="$_M/lib/python3.11/site-packages:$_C/lib/python3.11/site-packages${UNITAC_BASE_PYTHONPATH:+:$UNITAC_BASE_PYTHONPATH}"
export RMW_IMPLEMENTATION=rmw_fastrtps_cpp
# DDS stays on this machine (Kilted ignores ROS_LOCALHOST_ONLY; this works on Jazzy and Kilted).
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( $$ % 90 + 10 ))}"
unset _V _B _M _C _SITE _LIBS _d _PYLIBDIR _UNITAC_ROOT
