#!/usr/bin/env bash
# Setup, in stages: `scripts/setup.sh [STAGE...]` installs and builds what the named stages need
# (with what they need first), and with no stage all of them. Idempotent: each step keeps a stamp
# of its inputs and is skipped when they did not change (a re-run with nothing changed takes well
# under a second). Each step that has work to do says so in one line with its expected time.
#
# Stages (the times: first use, fresh machine of the project's kind, 2 cores):
#   run      what the main job needs (scripts/run, scripts/unitac): .venv with the pinned
#            packages of scripts/requirements-run.txt (ONNX Runtime, whose shared library the Rust
#            code loads; onnx, numpy: ~30 s, ~150 MB), the project's Python tools (python/, the
#            unitac_tools package, editable), and the reference model bundle in
#            .build/models/reference (`unitac-lab dataset fabrics` renders mock presses through the
#            real contact stage, unitac_tools.generate_reference builds the ONNX models and fits
#            the property head on them: ~1 min after the release build)
#   touch    + the touch projector in .build/models/touch (`unitac-lab dataset touch` pairs what the
#            camera and the sensor tell before contact with the encoder's latent of the touch,
#            training and unseen objects, GelSight Mini and DIGIT; unitac_tools.train_projector
#            trains the rectified-flow projector, evaluates it on the unseen objects (eval.json)
#            and fits the pooled-latent stiffness readout: ~5 min)
#   policy   + the reference policy in .build/models/policy (`unitac-lab demos` records the scripted
#            expert on training cups, and on unseen cups, scored only, through the vtla_real
#            scene's tactile stages; unitac_tools.fit_reference_policy fits the latent ->
#            stiffness readout and exports it to ONNX: ~2 min)
#   python   + the rest of scripts/requirements.txt in .venv: the ROS 2 Kilted wheels, rosidl
#            build helpers and colcon, rosbags, pyarrow, pytest, the benchmarks' Python baselines
#            (OpenCV, scipy, Pillow), the Robotiq client (~1.5 min, ~900 MB)
#   learned  + python, touch: the learned policies and their LeRobot datasets in
#            .build/models/learned (scripts/learned_policies.sh: expert demonstrations of both
#            tasks on training objects, LeRobot v3.0 datasets, unitac_tools.train_policy for
#            3 modes x 2 tasks x 3 training seeds: ~20 min)
#   ros      + python: ROS 2 Kilted for r2r and the ROS tests: apt packages libclang-dev (bindgen in
#            r2r), cmake (the interface packages), iproute2 and util-linux (the tests' network
#            namespace); the ROS-from-PyPI workarounds (../shared/notes/ros2-from-pypi.md and
#            scripts/env.sh): the librmw_implementation shim in .build/ros-shim and the rewrite of
#            build-container paths in the wheels' CMake; msg/unitac_msgs and msg/control_msgs (the
#            GripperCommand action of ros-controls/control_msgs, which no wheel carries) built
#            with plain cmake into .build/msgs/install and .build/control_msgs/install (~2 min)
#   jazzy    the second distro the ROS tests run on: .venv-jazzy with scripts/requirements-jazzy.txt,
#            its shim and messages in .build/jazzy (~2.5 min)
#   fonts    apt fonts-dejavu-core, the report charts' font (read by unitac-plot)
#   lab      python, touch, policy, fonts: what the benchmarks, reports, datasets and trials read
#   all      every stage (scripts/test, CI)
#   scene:NAME  the stages that make the models scene NAME names (scripts/unitac asks for the
#            scene it runs)
# A model step whose sources changed makes its data again and trains only if that data (or its
# trainer) differs from what its models were trained on (scripts/stamps.sh): a change that leaves
# the data byte-identical retrains nothing.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
BUILD="$ROOT/.build"
VENV="$ROOT/.venv"
VENV_JAZZY="$ROOT/.venv-jazzy"
MODELS="$BUILD/models"
mkdir -p "$BUILD"

log() { printf '[setup] %s\n' "$*" >&2; }
# shellcheck source=scripts/stamps.sh
source "$ROOT/scripts/stamps.sh"

# --- the stages asked for, with what they need -----------------------------------------------
# scene_stages NAME: the stages that make the models scene NAME names (a scene file's path, or a
# name in launch/scenes): ${UNITAC_MODELS}/<bundle>/... is made by the stage of that bundle.
scene_stages() {
  local f="$1" b
  [ -f "$f" ] || f="launch/scenes/$1.yaml"
  [ -f "$f" ] || return 0
  for b in $(grep -o 'UNITAC_MODELS}/[a-z_]*/' "$f" | cut -d/ -f2 | sort -u); do
    case "$b" in
      reference) echo run ;;
      touch | policy | learned) echo "$b" ;;
    esac
  done
}
declare -A want=()
need() {
  local s
  for s in "$@"; do
    [ -z "${want[$s]:-}" ] || continue
    want[$s]=1
    case "$s" in
      run) ;;
      touch | policy) need run ;;
      python) need run ;;
      learned) need python touch ;;
      ros) need python ;;
      jazzy | fonts) ;;
      lab) need python touch policy fonts ;;
      all) need run touch policy python learned ros jazzy fonts ;;
      scene:*) need $(scene_stages "${s#scene:}") ;;
      *)
        echo "setup: unknown stage '$s' (run, touch, policy, python, learned, ros, jazzy, fonts, lab, all, scene:NAME)" >&2
        exit 2
        ;;
    esac
  done
}
# Every stage runs on the main job's part: the ONNX Runtime library, the tools, the reference bundle.
need run
if (($#)); then need "$@"; else need all; fi
has() { [ -n "${want[$1]:-}" ]; }

# --- apt --------------------------------------------------------------------------------------
APT_PKGS=()
if has ros || has jazzy; then APT_PKGS+=(libclang-dev cmake iproute2 util-linux); fi
if has fonts; then APT_PKGS+=(fonts-dejavu-core); fi
missing=()
for p in "${APT_PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
if ((${#missing[@]})); then
  log "apt: installing ${missing[*]} (~1 min)"
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# --- Python venvs -----------------------------------------------------------------------------
PY="${UNITAC_PYTHON:-python3}"
py_ver="$("$PY" -c 'import sys; print("%d.%d" % sys.version_info[:2])')"
if [ "$py_ver" != "3.11" ]; then
  echo "setup: the ROS 2 wheels are built for CPython 3.11; '$PY' is $py_ver (set UNITAC_PYTHON)" >&2
  exit 2
fi
# make_venv VENV STAMP WHAT REQUIREMENTS...: the pinned packages of the requirements files in VENV
# (STAMP its stamp file there), and workaround 4 (the ROS wheels' exported CMake files point at
# their build container's Python).
make_venv() {
  local venv="$1" stamp="$2" what="$3" key real_inc np_inc
  shift 3
  venv_current "$venv" "$stamp" "$@" && return 0
  key="$(venv_key "$@")"
  log "venv: installing $1 into ${venv#"$ROOT"/} ($what)"
  [ -x "$venv/bin/python" ] || "$PY" -m venv "$venv"
  "$venv/bin/python" -m pip install -q --disable-pip-version-check -r "$1"
  real_inc="$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')"
  np_inc="$("$venv/bin/python" -c 'import numpy; print(numpy.get_include())')"
  # (grep finds nothing once rewritten: a re-install after a requirements change must not fail)
  { grep -rl --include='*.cmake' '/opt/python/cp311-cp311' "$venv/share" 2>/dev/null || true; } | while read -r f; do
    sed -i \
      -e "s#/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include#${np_inc}#g" \
      -e "s#/opt/python/cp311-cp311/include/python3.11#${real_inc}#g" "$f"
  done
  echo "$key" >"$venv/$stamp"
}
venv_key() { hash_of "$@" <(declare -f make_venv); }
# venv_current VENV STAMP REQUIREMENTS...: VENV holds those requirements as they are now.
venv_current() {
  local venv="$1" stamp="$2"
  shift 2
  [ "$(cat "$venv/$stamp" 2>/dev/null)" = "$(venv_key "$@")" ]
}
# release_build: the `unitac` binary and the lab's `unitac-lab`, whose datasets and demonstrations
# the model steps record (the first build takes minutes).
release_build() {
  [ -x target/release/unitac-lab ] \
    || log "cargo: building unitac and unitac-lab (release, first build: ~5 min on 2 cores)"
  cargo build --release --locked -q -p unitac-cli -p unitac-lab
}
# The main job's part of .venv: what the model steps read (their keys name this stamp). On a first
# run the release build, which needs no Python, goes on beside the install.
build_pid=""
if ! venv_current "$VENV" .unitac-run-stamp scripts/requirements-run.txt && [ ! -x target/release/unitac-lab ]; then
  (
    export UNITAC_ROS=kilted
    # shellcheck source=scripts/env.sh
    source "$ROOT/scripts/env.sh"
    release_build
  ) &
  build_pid=$!
fi
make_venv "$VENV" .unitac-run-stamp "~30 s, ~150 MB" scripts/requirements-run.txt
has python && make_venv "$VENV" .unitac-stamp "~1.5 min, ~900 MB" scripts/requirements.txt scripts/requirements-run.txt
has jazzy && make_venv "$VENV_JAZZY" .unitac-stamp "~2 min, ~400 MB" scripts/requirements-jazzy.txt
# The project's Python (python/: the unitac_tools package), editable in .venv: setup, the tests and
# a user run its tools as `python -m unitac_tools.<module>` from this checkout (pyproject.toml
# pins the setuptools that builds it; its own dependencies are requirements-run.txt's and, for
# the LeRobot datasets, requirements.txt's pyarrow).
install_tools() {
  local key
  key="$(hash_of python/pyproject.toml "$VENV/.unitac-run-stamp" <(declare -f install_tools; echo "$ROOT"))"
  [ "$(cat "$VENV/.unitac-tools-stamp" 2>/dev/null)" != "$key" ] || return 0
  log "venv: installing python/ (unitac_tools, editable) into .venv (~10 s)"
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check --no-deps -e python
  echo "$key" >"$VENV/.unitac-tools-stamp"
}
install_tools

# The venv and build outputs hold ROS package manifests of their own: a colcon workspace with
# this repository in its src must not take them for packages to build.
for d in "$VENV" "$BUILD" "${CARGO_TARGET_DIR:-$ROOT/target}"; do
  mkdir -p "$d" && [ -f "$d/COLCON_IGNORE" ] || : >"$d/COLCON_IGNORE"
done
if has jazzy; then [ -f "$VENV_JAZZY/COLCON_IGNORE" ] || : >"$VENV_JAZZY/COLCON_IGNORE"; fi

# --- ROS: the librmw_implementation shim (workaround 2), the interface packages -----------------
# make_shim DIR VENV: DIR/lib/librmw_implementation.so -> VENV's Fast DDS rmw (scripts/env.sh puts
# DIR on CMAKE_PREFIX_PATH).
make_shim() {
  if [ "$(readlink "$1/lib/librmw_implementation.so" 2>/dev/null)" != "$2/lib/librmw_fastrtps_cpp.so" ]; then
    mkdir -p "$1/lib"
    ln -sfn "$2/lib/librmw_fastrtps_cpp.so" "$1/lib/librmw_implementation.so"
  fi
}
# build_msgs B: the interface packages in msg/ into B/msgs/install with the environment of the
# distro that scripts/env.sh selected (UNITAC_VENV, CARGO_TARGET_DIR), B the distro's build dir.
build_msgs() {
  local b="$1" key
  key="$(hash_of $(find msg -type f | sort) "$UNITAC_VENV/.unitac-stamp")"
  [ "$(cat "$b/msgs/.stamp" 2>/dev/null)" != "$key" ] || return 0
  log "msgs: building msg/unitac_msgs and msg/control_msgs for $UNITAC_ROS (~1 min)"
  rm -rf "$b/msgs" "$b/control_msgs"
  mkdir -p "$b"
  : >"$b/msgs-cmake.log"
  # unitac_msgs is this repository's (colcon builds it too); control_msgs stands for the robot's
  # installed ros2_control interfaces: a prefix of its own, which colcon workspaces leave alone.
  local pkg prefix
  for pkg in unitac_msgs control_msgs; do
    prefix="$b/msgs"
    [ "$pkg" = unitac_msgs ] || prefix="$b/$pkg"
    cmake -S "msg/$pkg" -B "$prefix/build" -DCMAKE_INSTALL_PREFIX="$prefix/install" \
      -DBUILD_TESTING=OFF -DPython3_EXECUTABLE="$UNITAC_VENV/bin/python" >>"$b/msgs-cmake.log" 2>&1 \
      || { tail -50 "$b/msgs-cmake.log" >&2; exit 1; }
    cmake --build "$prefix/build" -j2 >>"$b/msgs-cmake.log" 2>&1 \
      && cmake --install "$prefix/build" >>"$b/msgs-cmake.log" 2>&1 \
      || { tail -50 "$b/msgs-cmake.log" >&2; exit 1; }
  done
  # r2r caches generated bindings in its OUT_DIR keyed on the environment, not on the message
  # files: drop both crates' build outputs so the bindings are generated again.
  if [ -d "${CARGO_TARGET_DIR:-target}" ]; then
    cargo clean -q -p r2r -p r2r_msg_gen 2>/dev/null || true
    cargo clean -q --release -p r2r -p r2r_msg_gen 2>/dev/null || true
  fi
  # The colcon check builds in its own target dir with an environment r2r has seen before: it would
  # keep the old bindings too, so it starts again from scratch.
  rm -rf "$b/colcon-target"
  echo "$key" >"$b/msgs/.stamp"
}
if has jazzy; then
  make_shim "$BUILD/jazzy/ros-shim" "$VENV_JAZZY"
  # In a subshell: the Kilted environment below is what the rest of setup uses.
  (
    export UNITAC_ROS=jazzy
    # shellcheck source=scripts/env.sh
    source "$ROOT/scripts/env.sh"
    build_msgs "$BUILD/jazzy"
  )
fi
export UNITAC_ROS=kilted
# shellcheck source=scripts/env.sh
source "$ROOT/scripts/env.sh"
if has ros; then
  make_shim "$BUILD/ros-shim" "$VENV"
  build_msgs "$BUILD"
fi

if [ -n "$build_pid" ]; then wait "$build_pid"; fi

# --- reference model bundle -------------------------------------------------------------------
models_inputs=(python/unitac_tools/generate_reference.py python/unitac_tools/schema.py Cargo.lock crates/lab/src/dataset.rs crates/infer/src/preprocess.rs
  $(find crates/sim/src crates/contact/src crates/core/src -name '*.rs' | sort))
models_key="$(hash_of "${models_inputs[@]}" "$VENV/.unitac-run-stamp")"
if [ "$(cat "$MODELS/.stamp" 2>/dev/null)" != "$models_key" ] || [ ! -f "$MODELS/reference/manifest.json" ]; then
  release_build
  log "models: the reference bundle's dataset from the mock sensor, then fitting (~1 min)"
  rm -rf "$MODELS/data" "$MODELS/reference.tmp"
  target/release/unitac-lab dataset fabrics --out "$MODELS/data"
  data_key="$(content_key "$MODELS/data" python/unitac_tools/generate_reference.py python/unitac_tools/schema.py crates/infer/src/preprocess.rs "$VENV/.unitac-run-stamp")"
  if stands "$MODELS/reference" "$data_key" && [ -f "$MODELS/reference/manifest.json" ]; then
    log "models: the dataset is byte-identical to the reference bundle's: the bundle stands"
  else
    "$VENV/bin/python" -m unitac_tools.generate_reference "$MODELS/reference.tmp" --data "$MODELS/data" >"$MODELS/fit.json"
    echo "$data_key" >"$MODELS/reference.tmp/.data-key"
    rm -rf "$MODELS/reference"
    mv "$MODELS/reference.tmp" "$MODELS/reference"
  fi
  rm -rf "$MODELS/data"
  echo "$models_key" >"$MODELS/.stamp"
fi

# --- touch projector --------------------------------------------------------------------------
# The camera's values and sensor prior of training objects before contact, with the encoder's
# latent of their touch, on two sensors (`unitac-lab dataset touch`); unitac_tools.train_projector
# trains the rectified-flow projector on the training split, evaluates it on the unseen split
# and writes the bundle (encoder + projector + the pooled-latent stiffness readout).
TOUCH="$MODELS/touch"
touch_inputs=(python/unitac_tools/train_projector.py Cargo.lock crates/lab/src/touch_dataset.rs crates/lab/src/dataset.rs
  launch/scenes/cup_deformation_vtla_real.yaml objects/split.yaml
  $(find crates/sim/src crates/contact/src crates/core/src crates/infer/src crates/trials/src crates/pipeline/src crates/policy/src -name '*.rs' | sort))
touch_key="$(hash_of "${touch_inputs[@]}" "$MODELS/reference/manifest.json")"
if has touch && { [ "$(cat "$TOUCH/.stamp" 2>/dev/null)" != "$touch_key" ] || [ ! -f "$TOUCH/manifest.json" ]; }; then
  release_build
  log "touch projector: touch dataset of training and unseen objects (~2 min), then training (~3 min)"
  rm -rf "$TOUCH.tmp" && mkdir -p "$TOUCH.tmp/data"
  for s in gelsight-mini digit; do
    target/release/unitac-lab dataset touch --split train --seeds 1,2,3 --trials 20 --sensor "$s" \
      --out "$TOUCH.tmp/data/train-$s" >&2
    target/release/unitac-lab dataset touch --split unseen --seeds 101,102,103 --trials 20 --sensor "$s" \
      --out "$TOUCH.tmp/data/unseen-$s" >&2
  done
  data_key="$(content_key "$TOUCH.tmp/data" python/unitac_tools/train_projector.py python/unitac_tools/generate_reference.py \
    python/unitac_tools/schema.py schema/policy.json "$MODELS/reference/manifest.json")"
  if stands "$TOUCH" "$data_key" && [ -f "$TOUCH/manifest.json" ]; then
    log "touch projector: the dataset is byte-identical to the projector's: it stands"
    rm -rf "$TOUCH.tmp"
  else
    "$VENV/bin/python" -m unitac_tools.train_projector --train "$TOUCH.tmp"/data/train-*/touch.json \
      --unseen "$TOUCH.tmp"/data/unseen-*/touch.json --reference "$MODELS/reference" --out "$TOUCH.tmp" >/dev/null
    echo "$data_key" >"$TOUCH.tmp/.data-key"
    rm -rf "$TOUCH.tmp/data" "$TOUCH"
    mv "$TOUCH.tmp" "$TOUCH"
  fi
  echo "$touch_key" >"$TOUCH/.stamp"
fi

# --- reference policy -------------------------------------------------------------------------
POLICIES="$MODELS/policy"
policy_inputs=(python/unitac_tools/fit_reference_policy.py Cargo.lock launch/scenes/cup_deformation_vtla_real.yaml
  crates/lab/src/demos.rs
  $(find crates/sim/src crates/contact/src crates/core/src crates/infer/src crates/trials/src crates/pipeline/src crates/policy/src -name '*.rs' | sort))
policy_key="$(hash_of "${policy_inputs[@]}" "$MODELS/reference/manifest.json")"
if has policy && { [ "$(cat "$POLICIES/.stamp" 2>/dev/null)" != "$policy_key" ] || [ ! -f "$POLICIES/cup_stiffness_real/manifest.json" ]; }; then
  release_build
  log "policies: expert demonstrations on training cups, fitting the stiffness readout (~2 min)"
  rm -rf "$POLICIES.tmp"
  mkdir -p "$POLICIES.tmp"
  demos="$POLICIES.tmp/demos"
  target/release/unitac-lab demos --scene cup_deformation_vtla_real --split train --seeds 1,2,3 --trials 20 --out "$demos/train" >&2
  target/release/unitac-lab demos --scene cup_deformation_vtla_real --split unseen --seeds 101,102 --trials 10 --out "$demos/unseen" >&2
  data_key="$(content_key "$demos" python/unitac_tools/fit_reference_policy.py python/unitac_tools/schema.py schema/policy.json \
    "$VENV/.unitac-run-stamp")"
  if stands "$POLICIES" "$data_key" && [ -f "$POLICIES/cup_stiffness_real/manifest.json" ]; then
    log "policies: the demonstrations are byte-identical to the readout's: it stands"
    rm -rf "$POLICIES.tmp"
  else
    "$VENV/bin/python" -m unitac_tools.fit_reference_policy --train "$demos/train/demos.json" \
      --eval "$demos/unseen/demos.json" --source real --name cup_stiffness_real \
      --out "$POLICIES.tmp/cup_stiffness_real" >/dev/null
    echo "$data_key" >"$POLICIES.tmp/.data-key"
    rm -rf "$POLICIES.tmp/demos" "$POLICIES"
    mv "$POLICIES.tmp" "$POLICIES"
  fi
  echo "$policy_key" >"$POLICIES/.stamp"
fi

# --- learned policies -------------------------------------------------------------------------
if has learned; then bash scripts/learned_policies.sh; fi
done_stages=()
for s in run touch policy python learned ros jazzy fonts; do has "$s" && done_stages+=("$s"); done
log "ready: ${done_stages[*]}"
