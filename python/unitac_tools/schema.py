"""The policies' data layout from schema/policy.json, the one file the Rust side also reads (at
build time, crates/policy/build.rs): the observation features (LeRobot keys, value names, units),
what each mode's learned policy reads, the command actions, the cup stiffness readout, and the one
writer of a policy bundle's manifest.json (crates/policy/src/onnx/manifest.rs reads it).

Run as a script it prints, as JSON, what Python reads from the file; the Rust test
`cargo test -p unitac-policy --test schema` compares that with the generated constants.
"""
import hashlib
import json
import os

# The repository root: this package lives in its python/ directory.
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PATH = os.path.join(ROOT, "schema", "policy.json")

with open(PATH) as _f:
    SCHEMA = json.load(_f)

_BY_ID = {f["id"]: f for f in SCHEMA["features"]}


def key(feature_id):
    """The LeRobot key of the feature `feature_id` ("state" -> "observation.state")."""
    return _BY_ID[feature_id]["key"]


def names(feature_id):
    """What each value of a fixed-width feature is (None: its width is the scene's)."""
    n = _BY_ID[feature_id]["names"]
    return None if n is None else list(n)


STATE, VISUAL, LATCHED, ARM = key("state"), key("visual"), key("latched"), key("arm")
CONTACT, COMPARISON, LATENT = key("contact"), key("comparison"), key("latent")
LATENT_REAL, LATENT_PRED = key("latent_real"), key("latent_pred")
STATE_NAMES, LATCHED_NAMES, ARM_NAMES = names("state"), names("latched"), names("arm")
CONTACT_NAMES, COMPARISON_NAMES = names("contact"), names("comparison")
MAX_SINCE_TARGET_S = float(SCHEMA["max_since_target_s"])

MODES = [m["mode"] for m in SCHEMA["modes"]]
# Per mode, the feature keys its learned policy reads, in this order.
LEARNED_FEATURES = {m["mode"]: [key(i) for i in m["learned_features"]] for m in SCHEMA["modes"]}
# The observation features a demonstration dataset records, (id, key) in the schema's order:
# every one some mode's learned policy reads. The id is the demonstration tick's field.
DATASET_FEATURES = [(f["id"], f["key"]) for f in SCHEMA["features"]
                    if any(f["id"] in m["learned_features"] for m in SCHEMA["modes"])]

_A = SCHEMA["actions"]
ACTION = _A["key"]
COMMANDS = list(_A["names"])
UNITS = dict(zip(_A["names"], _A["units"]))
ARM_TARGET = _A["arm_target_key"]
ARM_TARGET_PREFIX = _A["arm_target_prefix"]
ARM_TARGET_UNIT = _A["arm_target_unit"]
FAR_FRACTION = float(_A["far_fraction"])

_K = SCHEMA["stiffness"]
STIFFNESS_INPUT = key(_K["input"])
STIFFNESS_ACTION = _K["action"]
STIFFNESS_UNIT = _K["unit"]
K_MIN, K_MAX, PRIOR_K = float(_K["min"]), float(_K["max"]), float(_K["prior"])

_M = SCHEMA["manifest"]
ONNX_FILE, OUTPUT, DTYPE = _M["file"], _M["output"], _M["dtype"]


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def stiffness_actions():
    """The stiffness readout's one action, bounded to the schema's range."""
    return [{"name": STIFFNESS_ACTION, "unit": STIFFNESS_UNIT, "min": K_MIN, "max": K_MAX}]


def write_policy_manifest(out_dir, policy, description, control_rate_hz, inputs, actions,
                          output_normalization, chunk_size=1, n_action_steps=1,
                          temporal_ensemble_coeff=None):
    """Write out_dir/manifest.json for out_dir/policy.onnx (already saved): `inputs` are
    {name, shape, normalization[, names]} (dtype added), `actions` {name, unit, min, max}; the
    output is the action chunk [batch, chunk_size, len(actions)]."""
    manifest = {
        "policy": policy,
        "version": "1",
        "description": description,
        "file": ONNX_FILE,
        "sha256": sha256(os.path.join(out_dir, ONNX_FILE)),
        "control_rate_hz": float(control_rate_hz),
        "chunk_size": chunk_size,
        "n_action_steps": n_action_steps,
        "temporal_ensemble_coeff": temporal_ensemble_coeff,
        "inputs": [{"name": i["name"], "dtype": DTYPE, **{k: v for k, v in i.items() if k != "name"}}
                   for i in inputs],
        "output": {"name": OUTPUT, "dtype": DTYPE, "shape": ["batch", chunk_size, len(actions)],
                   "normalization": output_normalization, "actions": actions},
    }
    with open(os.path.join(out_dir, "manifest.json"), "w") as f:
        json.dump(manifest, f, indent=1, allow_nan=False)
    return manifest


def dump():
    """What Python reads from the schema, for the Rust side's comparison."""
    return {
        "features": {k: names(i) for i, k in ((f["id"], f["key"]) for f in SCHEMA["features"])},
        "fixed": {STATE: STATE_NAMES, LATCHED: LATCHED_NAMES, ARM: ARM_NAMES, CONTACT: CONTACT_NAMES,
                  COMPARISON: COMPARISON_NAMES},
        "max_since_target_s": MAX_SINCE_TARGET_S,
        "modes": MODES,
        "learned_features": LEARNED_FEATURES,
        "dataset_features": [list(f) for f in DATASET_FEATURES],
        "action": ACTION,
        "commands": COMMANDS,
        "units": [UNITS[c] for c in COMMANDS],
        "arm_target": ARM_TARGET,
        "arm_target_prefix": ARM_TARGET_PREFIX,
        "arm_target_unit": ARM_TARGET_UNIT,
        "far_fraction": FAR_FRACTION,
        "stiffness": {"input": STIFFNESS_INPUT, "action": STIFFNESS_ACTION, "unit": STIFFNESS_UNIT,
                      "min": K_MIN, "max": K_MAX, "prior": PRIOR_K},
        "manifest": {"file": ONNX_FILE, "output": OUTPUT, "dtype": DTYPE},
    }


if __name__ == "__main__":
    print(json.dumps(dump(), indent=1))
