# Environment for building and running the workspace (sourced by scripts/run, scripts/test,
# scripts/unitac and scripts/setup.sh; never needed by hand). Paths are derived from the repo root.
# The four ROS-from-PyPI workarounds live here and in setup.sh (../shared/notes/ros2-from-pypi.md).
_UNITAC_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
_V="$_UNITAC_ROOT/.venv"
_M="$_UNITAC_ROOT/.build/msgs/install"
_SITE="$_V/lib/python3.11/site-packages"
export UNITAC_ROOT="$_UNITAC_ROOT"
export UNITAC_VENV="$_V"
# ONNX Runtime shared library from the pinned wheel (ort load-dynamic).
# Generated model bundles (scripts/setup.sh step 5).
export UNITAC_MODELS="$_UNITAC_ROOT/.build/models"
export UNITAC_ORT_LIB="$_SITE/onnxruntime/capi/libonnxruntime.so.1.31.1"
# libpython for binaries that link r2r (workaround 3; crates/ros/build.rs reads this).
_PYLIBDIR="$("$_V/bin/python" -c 'import sysconfig; print(sysconfig.get_config_var("LIBDIR"))' 2>/dev/null || true)"
export UNITAC_PYTHON_LIBDIR="$_PYLIBDIR"
export AMENT_PREFIX_PATH="$_M:$_V"
# Workaround 2: librmw_implementation.so shim directory on CMAKE_PREFIX_PATH.
export CMAKE_PREFIX_PATH="$AMENT_PREFIX_PATH:$_UNITAC_ROOT/.build/ros-shim"
# Workaround 1: r2r 0.9.7 does not know "kilted"; the bindings still come from the Kilted headers.
export ROS_DISTRO=jazzy
_LIBS="$_M/lib:$_V/lib"
for _d in "$_SITE"/ros_*.libs "$_SITE"/numpy.libs; do [ -d "$_d" ] && _LIBS="$_LIBS:$_d"; done
[ -n "$_PYLIBDIR" ] && _LIBS="$_LIBS:$_PYLIBDIR"
export LD_LIBRARY_PATH="$_LIBS${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export PYTHONPATH="$_M/lib/python3.11/site-packages${PYTHONPATH:+:$PYTHONPATH}"
export RMW_IMPLEMENTATION=rmw_fastrtps_cpp
# DDS stays on this machine (Kilted ignores ROS_LOCALHOST_ONLY).
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( $$ % 90 + 10 ))}"
unset _V _M _SITE _LIBS _d _PYLIBDIR _UNITAC_ROOT
