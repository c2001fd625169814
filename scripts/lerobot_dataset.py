"""Write `unitac demos` demonstrations (demos.json) as a LeRobot dataset, layout v3.0.

usage: lerobot_dataset.py --demos DEMOS.json --out DIR [--robot-type NAME]

Why Python: pyarrow writes Parquet with the exact Arrow types LeRobot's loader expects
(fixed-size lists for vector features, plain scalars for shape-[1] ones, a pandas-indexed
tasks table) in one small dependency; doing it in Rust would pull the arrow/parquet crates into
the workspace build for one writer. The Rust side (crates/trials/src/demos.rs) records; this
script only lays the recorded ticks out, it computes nothing a policy sees.

One demonstration = one episode, one control tick = one frame (fps = 1 / the demos' dt_s). The
layout (LeRobot's v3.0, read by LeRobotDataset in lerobot 0.4.x):

    meta/info.json                        codebase_version, fps, features (dtype, shape, names),
                                          data_path / video_path templates, chunks_size, totals
    meta/stats.json                       per feature: min, max, mean, std, count (all frames)
    meta/tasks.parquet                    task_index, indexed by the task text (pandas index)
    meta/episodes/chunk-000/file-000.parquet
                                          episode_index, tasks, length, data/chunk_index,
                                          data/file_index, dataset_from_index, dataset_to_index,
                                          meta/episodes/{chunk,file}_index, stats/<feature>/<stat>,
                                          and the demonstration's seed, trial, success
    data/chunk-000/file-000.parquet       the features, timestamp, frame_index, episode_index,
                                          index, task_index

Features (float32 unless said): observation.state [8] (the gripper status as the policy reads
it), observation.visual [V] (the mean of the camera's estimates so far), observation.contact [3],
observation.latched [2] (the opening at the first object-detect, known), observation.arm [2] (time
since the commanded arm target last changed, at most 10 s, and whether the arm had its travel time),
observation.tactile_latent_real and observation.tactile_latent_pred [objects x (P + 1)] (per
object the pooled latent, then known), observation.comparison [5], action [7] (the gripper's
position, speed, force limit and the arm's x, y, z, lift: the policy's action values; its
info.json entry has `bounds`, {min, max} per value: the range the recording scene's safety layer
held it to), action.arm_target [1] (int64: 0 home, k + 1 object k; its info.json entry lists them
as `categories`).
"""
import argparse
import json
import math
import os
import sys

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

CODEBASE_VERSION = "v3.0"
CHUNKS_SIZE = 1000
DATA_FILE_SIZE_IN_MB = 100
VIDEO_FILE_SIZE_IN_MB = 200
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
EPISODES_PATH = "meta/episodes/chunk-000/file-000.parquet"
# Bounds on what one demos.json may ask for.
MAX_EPISODES = 10_000
MAX_FRAMES = 2_000_000
MAX_WIDTH = 4096

STATE_NAMES = ["opening_m", "target_m", "target_known", "force_n", "force_known",
               "current_a", "current_known", "object_detected"]
CONTACT_NAMES = ["in_contact", "area_mm2", "strength"]
LATCHED_NAMES = ["opening_at_object_detect_m", "known"]
ARM_NAMES = ["since_target_s", "travelled"]
COMPARISON_NAMES = ["winner_a", "winner_b", "tie", "margin", "confidence"]
INDEX_FEATURES = {
    "timestamp": {"dtype": "float32", "shape": [1], "names": None},
    "frame_index": {"dtype": "int64", "shape": [1], "names": None},
    "episode_index": {"dtype": "int64", "shape": [1], "names": None},
    "index": {"dtype": "int64", "shape": [1], "names": None},
    "task_index": {"dtype": "int64", "shape": [1], "names": None},
}


def fail(msg):
    raise SystemExit(f"lerobot_dataset: {msg}")


def latent_names(objects, width):
    half = width // 2
    names = []
    for o in objects:
        names += [f"{o}.mean_{j}" for j in range(half)]
        names += [f"{o}.meansq_{j}" for j in range(width - half)]
        names.append(f"{o}.known")
    return names


def features_of(d):
    """The dataset's features (tick field, LeRobot key, dtype, names) from a demos.json."""
    first = d["demos"][0]
    objects = first["objects"]
    width = int(d["config"]["pooled_len"])
    if not (1 <= width <= MAX_WIDTH) or not (1 <= len(objects) <= 16):
        fail(f"pooled_len {width} or {len(objects)} objects out of bounds")
    return [
        ("state", "observation.state", "float32", STATE_NAMES),
        ("visual", "observation.visual", "float32", list(first["visual_names"])),
        ("contact", "observation.contact", "float32", CONTACT_NAMES),
        ("latched", "observation.latched", "float32", LATCHED_NAMES),
        ("arm", "observation.arm", "float32", ARM_NAMES),
        ("latent_real", "observation.tactile_latent_real", "float32", latent_names(objects, width)),
        ("latent_pred", "observation.tactile_latent_pred", "float32", latent_names(objects, width)),
        ("comparison", "observation.comparison", "float32", COMPARISON_NAMES),
        ("action", "action", "float32", list(d["action_names"])),
        ("arm_target", "action.arm_target", "int64", ["arm_target"]),
    ]


def stats_of(x):
    """LeRobot's per-feature statistics of frames x [n, dim] (count: frames)."""
    x = np.asarray(x, np.float64)
    return {
        "min": x.min(axis=0),
        "max": x.max(axis=0),
        "mean": x.mean(axis=0),
        "std": x.std(axis=0),
        "count": np.array([x.shape[0]], np.int64),
    }


def action_bounds(d):
    """{min, max}, per action value in action_names order, from the demos' action_bounds."""
    b = d.get("action_bounds")
    if not isinstance(b, dict):
        fail("demos.json has no action_bounds")
    lo, hi = [], []
    for n in d["action_names"]:
        r = b.get(n)
        if not (isinstance(r, list) and len(r) == 2 and all(isinstance(v, (int, float)) and math.isfinite(v) for v in r)
                and r[0] < r[1]):
            fail(f"action_bounds: {n}: {r!r} is not a finite [min, max]")
        lo.append(float(r[0]))
        hi.append(float(r[1]))
    return {"min": lo, "max": hi}


def tasks_table(task):
    """meta/tasks.parquet as pandas writes DataFrame({'task_index': [0]}, index=[task]): the
    loader reads it with pandas and looks tasks up by the index."""
    pandas_meta = {
        "index_columns": ["__index_level_0__"],
        "column_indexes": [{"name": None, "field_name": None, "pandas_type": "unicode",
                            "numpy_type": "object", "metadata": {"encoding": "UTF-8"}}],
        "columns": [
            {"name": "task_index", "field_name": "task_index", "pandas_type": "int64",
             "numpy_type": "int64", "metadata": None},
            {"name": None, "field_name": "__index_level_0__", "pandas_type": "unicode",
             "numpy_type": "object", "metadata": None},
        ],
        "creator": {"library": "pyarrow", "version": pa.__version__},
        "pandas_version": "2.2.3",
    }
    schema = pa.schema([("task_index", pa.int64()), ("__index_level_0__", pa.string())],
                       metadata={b"pandas": json.dumps(pandas_meta).encode()})
    return pa.table({"task_index": [0], "__index_level_0__": [task]}, schema=schema)


def vector_column(rows, dim, dtype):
    flat = np.asarray(rows, dtype).reshape(-1)
    if flat.size != len(rows) * dim:
        fail(f"a column has rows of another width than {dim}")
    return pa.FixedSizeListArray.from_arrays(pa.array(flat), dim)


def write(d, out, robot_type):
    demos = d["demos"]
    if not demos or len(demos) > MAX_EPISODES:
        fail(f"{len(demos)} demonstrations (1 to {MAX_EPISODES})")
    dt = float(d["config"]["dt_s"])
    fps = 1.0 / dt
    if not (math.isfinite(fps) and abs(fps - round(fps)) < 1e-6 and 1 <= round(fps) <= 1000):
        fail(f"dt_s {dt} is not 1 / an integer rate")
    fps = int(round(fps))
    feats = features_of(d)
    frames = sum(len(e["ticks"]) for e in demos)
    if frames == 0 or frames > MAX_FRAMES:
        fail(f"{frames} frames (1 to {MAX_FRAMES})")
    # Frame columns, all episodes in one file (the loader globs data/*/*.parquet).
    cols = {key: [] for _, key, _, _ in feats}
    ts, frame_index, episode_index, index = [], [], [], []
    episodes = []
    start = 0
    for e, demo in enumerate(demos):
        ticks = demo["ticks"]
        if demo["objects"] != demos[0]["objects"] or demo["visual_names"] != demos[0]["visual_names"]:
            fail(f"demonstration {e}: other objects or camera values than the first")
        ep_cols = {}
        for field, key, _, names in feats:
            rows = [t[field] if isinstance(t[field], list) else [t[field]] for t in ticks]
            if any(len(r) != len(names) for r in rows):
                fail(f"demonstration {e}: {key} is not {len(names)} wide")
            cols[key] += rows
            ep_cols[key] = rows
        n = len(ticks)
        ts += [k / fps for k in range(n)]
        frame_index += list(range(n))
        episode_index += [e] * n
        index += list(range(start, start + n))
        ep = {
            "episode_index": e,
            "tasks": [d["instruction"]],
            "length": n,
            "data/chunk_index": 0,
            "data/file_index": 0,
            "dataset_from_index": start,
            "dataset_to_index": start + n,
            "meta/episodes/chunk_index": 0,
            "meta/episodes/file_index": 0,
            "seed": int(demo["seed"]),
            "trial": int(demo["trial"]),
            "success": bool(demo["success"]),
        }
        per = {key: stats_of(rows) for key, rows in ep_cols.items()}
        per["timestamp"] = stats_of([[k / fps] for k in range(n)])
        per["frame_index"] = stats_of([[k] for k in range(n)])
        per["episode_index"] = stats_of([[e]] * n)
        per["index"] = stats_of([[i] for i in range(start, start + n)])
        per["task_index"] = stats_of([[0]] * n)
        for key, s in per.items():
            for stat, v in s.items():
                ep[f"stats/{key}/{stat}"] = v
        episodes.append(ep)
        start += n

    arrays, fields = [], []
    for _, key, dtype, names in feats:
        if len(names) == 1:
            arrays.append(pa.array(np.asarray(cols[key], dtype).reshape(-1)))
        else:
            arrays.append(vector_column(cols[key], len(names), dtype))
        fields.append(key)
    for key, values, dtype in [("timestamp", ts, np.float32), ("frame_index", frame_index, np.int64),
                               ("episode_index", episode_index, np.int64),
                               ("index", index, np.int64), ("task_index", [0] * frames, np.int64)]:
        arrays.append(pa.array(np.asarray(values, dtype)))
        fields.append(key)
    data = pa.Table.from_arrays(arrays, names=fields)

    features = {key: {"dtype": dtype, "shape": [len(names)], "names": names}
                for _, key, dtype, names in feats}
    # The arm target's values: 0 home, k + 1 object k.
    features["action.arm_target"]["categories"] = ["home"] + list(demos[0]["objects"])
    features["action"]["bounds"] = action_bounds(d)
    features.update(INDEX_FEATURES)
    info = {
        "codebase_version": CODEBASE_VERSION,
        "robot_type": robot_type,
        "total_episodes": len(demos),
        "total_frames": frames,
        "total_tasks": 1,
        "chunks_size": CHUNKS_SIZE,
        "data_files_size_in_mb": DATA_FILE_SIZE_IN_MB,
        "video_files_size_in_mb": VIDEO_FILE_SIZE_IN_MB,
        "fps": fps,
        "splits": {"train": f"0:{len(demos)}"},
        "data_path": DATA_PATH,
        "video_path": None,
        "features": features,
    }
    stats = {key: stats_of(np.asarray(cols[key], np.float64).reshape(frames, -1))
             for _, key, _, _ in feats}
    stats["timestamp"] = stats_of(np.asarray(ts).reshape(-1, 1))
    stats["frame_index"] = stats_of(np.asarray(frame_index).reshape(-1, 1))
    stats["episode_index"] = stats_of(np.asarray(episode_index).reshape(-1, 1))
    stats["index"] = stats_of(np.asarray(index).reshape(-1, 1))
    stats["task_index"] = stats_of(np.zeros((frames, 1)))

    # Episode table: one row per episode; stats as float64 lists (count: int64 list).
    ep_cols = {k: [ep[k] for ep in episodes] for k in episodes[0]}
    ep_arrays = {}
    for k, v in ep_cols.items():
        if k.startswith("stats/"):
            dt_ = pa.int64() if k.endswith("/count") else pa.float64()
            ep_arrays[k] = pa.array([list(map(float if dt_ == pa.float64() else int, x)) for x in v],
                                    type=pa.list_(dt_))
        elif k == "tasks":
            ep_arrays[k] = pa.array(v, type=pa.list_(pa.string()))
        elif k == "success":
            ep_arrays[k] = pa.array(v, type=pa.bool_())
        else:
            ep_arrays[k] = pa.array(v, type=pa.int64())
    ep_table = pa.table(ep_arrays)

    os.makedirs(os.path.join(out, "meta", "episodes", "chunk-000"), exist_ok=True)
    os.makedirs(os.path.join(out, "data", "chunk-000"), exist_ok=True)
    pq.write_table(data, os.path.join(out, DATA_PATH.format(chunk_index=0, file_index=0)))
    pq.write_table(ep_table, os.path.join(out, EPISODES_PATH))
    pq.write_table(tasks_table(d["instruction"]), os.path.join(out, "meta", "tasks.parquet"))
    with open(os.path.join(out, "meta", "info.json"), "w") as f:
        json.dump(info, f, indent=4)
    with open(os.path.join(out, "meta", "stats.json"), "w") as f:
        json.dump({k: {s: v.tolist() for s, v in st.items()} for k, st in stats.items()}, f, indent=4)
    return len(demos), frames


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--demos", required=True, help="demos.json of `unitac demos`")
    ap.add_argument("--out", required=True, help="the dataset's root directory")
    ap.add_argument("--robot-type", default="unitac_sim_two_finger")
    a = ap.parse_args(argv)
    with open(a.demos) as f:
        d = json.load(f)
    n, frames = write(d, a.out, a.robot_type)
    print(f"{n} episodes, {frames} frames of '{d['instruction']}' in {a.out}")


if __name__ == "__main__":
    sys.exit(main())
