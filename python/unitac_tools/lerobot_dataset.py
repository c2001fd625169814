"""Write `unitac-lab demos` demonstrations (demos.json) as a LeRobot dataset, layout v3.0.

usage: python -m unitac_tools.lerobot_dataset --demos DEMOS.json --out DIR [--robot-type NAME]

Every value is checked before anything is written: each feature's values are numbers (the arm
target an integer), finite and at most MAX_ABS in magnitude, each action value inside its
`action_bounds` (compared as the float32 the dataset stores), the arm target one of its categories
(0 home, k + 1 object k of the demonstration's `objects`). The first bad value, key or type ends
the run with exit 1 and one line on stderr naming the episode, tick and feature; nothing is
written then. The dataset is written into a hidden directory beside DIR and renamed to DIR at the
end; an existing DIR must be empty or a dataset (meta/info.json and nothing but meta/, data/,
videos/ at its top), which is then replaced.

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

Features: those of schema/policy.json (read through python/unitac_tools/schema.py), float32: every
observation feature a mode's learned policy reads (observation.visual has the scene's names, the
per-object latent slots objects x (P + 1): the pooled latent, then known), then action (the
policy's command values; its info.json entry has `bounds`, {min, max} per value: the range the
recording scene's safety layer held it to), and action.arm_target [1] (int64: 0 home, k + 1
object k; its info.json entry lists them as `categories`).
"""
import argparse
import json
import math
import os
import shutil
import sys
import tempfile

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from . import schema

CODEBASE_VERSION = "v3.0"
CHUNKS_SIZE = 1000
DATA_FILE_SIZE_IN_MB = 100
VIDEO_FILE_SIZE_IN_MB = 200
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
EPISODES_PATH = "meta/episodes/chunk-000/file-000.parquet"
# Bounds on what one demos.json may ask for.
MAX_BYTES = 8 << 30
MAX_EPISODES = 10_000
MAX_FRAMES = 2_000_000
MAX_WIDTH = 4096
MAX_OBJECTS = 16
MAX_NAMES = 256
MAX_TEXT = 1000
MAX_SEED = (1 << 63) - 1
# The largest magnitude of any float value: far beyond every observation and action the stack
# produces (metres, newtons, amperes, mm^2, latents of order 1), far inside float32.
MAX_ABS = 1e6
# The top-level entries of a dataset directory that --out may replace.
DATASET_ENTRIES = {"meta", "data", "videos"}

INDEX_FEATURES = {
    "timestamp": {"dtype": "float32", "shape": [1], "names": None},
    "frame_index": {"dtype": "int64", "shape": [1], "names": None},
    "episode_index": {"dtype": "int64", "shape": [1], "names": None},
    "index": {"dtype": "int64", "shape": [1], "names": None},
    "task_index": {"dtype": "int64", "shape": [1], "names": None},
}


class Refused(Exception):
    """A demos.json or an output path this script will not write a dataset from or to."""


def fail(msg):
    raise Refused(msg)


def show(v, limit=60):
    """A value from the input as a short piece of one line."""
    if isinstance(v, float):
        s = repr(v)
    else:
        try:
            s = json.dumps(v, ensure_ascii=True, allow_nan=True)
        except (TypeError, ValueError, RecursionError):
            s = type(v).__name__
    return s if len(s) <= limit else s[:limit - 3] + "..."


def kind_of(v):
    """The JSON kind of a value json.load gave."""
    if isinstance(v, bool):
        return "boolean"
    if isinstance(v, int):
        return "integer"
    if isinstance(v, float):
        return "number"
    if v is None:
        return "null"
    return {dict: "object", list: "array", str: "string"}.get(type(v), type(v).__name__)


def article(kind):
    """A JSON kind with its article: 'an array', 'a number'."""
    return ("an " if kind[0] in "aeiou" else "a ") + kind


def need(obj, key, kind, where):
    """obj[key], which must be of the JSON kind ('object', 'array', 'string', 'boolean',
    'integer', 'number')."""
    if key not in obj:
        fail(f"{where}: no {key!r}")
    v = obj[key]
    k = kind_of(v)
    if not (k == kind or (kind == "number" and k == "integer")):
        fail(f"{where}: {key} is {article(k)} ({show(v)}), not {article(kind)}")
    return v


def need_strings(obj, key, where, lo, hi):
    """obj[key]: an array of lo..hi distinct non-empty strings of at most MAX_TEXT characters."""
    v = need(obj, key, "array", where)
    if not lo <= len(v) <= hi:
        fail(f"{where}: {key} has {len(v)} entries ({lo} to {hi})")
    for i, s in enumerate(v):
        if not (isinstance(s, str) and 1 <= len(s) <= MAX_TEXT):
            fail(f"{where}: {key}[{i}] is {show(s)}, not a non-empty string")
    if len(set(v)) != len(v):
        fail(f"{where}: {key} names one entry twice")
    return v


def latent_names(objects, width):
    half = width // 2
    names = []
    for o in objects:
        names += [f"{o}.mean_{j}" for j in range(half)]
        names += [f"{o}.meansq_{j}" for j in range(width - half)]
        names.append(f"{o}.known")
    return names


def features_of(d, first):
    """The dataset's features (tick field, LeRobot key, dtype, names) from a demos.json."""
    objects = need_strings(first, "objects", "episode 0", 1, MAX_OBJECTS)
    visual = need_strings(first, "visual_names", "episode 0", 1, MAX_NAMES)
    config = need(d, "config", "object", "demos.json")
    width = need(config, "pooled_len", "integer", "demos.json: config")
    if not 1 <= width <= MAX_WIDTH:
        fail(f"demos.json: config: pooled_len {width} (1 to {MAX_WIDTH})")
    scene = {"visual": list(visual), "latent_real": latent_names(objects, width),
             "latent_pred": latent_names(objects, width)}
    return [(i, k, "float32", schema.names(i) or scene[i]) for i, k in schema.DATASET_FEATURES] + [
        ("action", schema.ACTION, "float32", list(d["action_names"])),
        ("arm_target", schema.ARM_TARGET, "int64", ["arm_target"]),
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


def action_bounds(d, names):
    """{min, max}, per action value in action_names order, from the demos' action_bounds."""
    b = need(d, "action_bounds", "object", "demos.json")
    lo, hi = [], []
    for n in names:
        r = b.get(n)
        if not (isinstance(r, list) and len(r) == 2 and all(kind_of(v) in ("integer", "number") for v in r)
                and all(math.isfinite(v) and abs(v) <= MAX_ABS for v in r) and r[0] < r[1]):
            fail(f"demos.json: action_bounds: {n}: {show(r)} is not a finite [min, max] "
                 f"within +-{MAX_ABS:g}")
        lo.append(float(r[0]))
        hi.append(float(r[1]))
    return {"min": lo, "max": hi}


def float_rows(ticks, field, key, names, e, limits):
    """The episode's values of one float feature as [ticks, width] float64, each a number, finite
    and inside limits ([lo, hi] per value, float32 as stored) or refused, naming where."""
    w = len(names)
    for t, tick in enumerate(ticks):
        r = need(tick, field, "array", f"episode {e}, tick {t}")
        if len(r) != w:
            fail(f"episode {e}, tick {t}: {key} has {len(r)} values, not {w}")
        for i, v in enumerate(r):
            if type(v) is not float and type(v) is not int:
                fail(f"episode {e}, tick {t}: {key}[{i}] ({names[i]}) is {show(v)}, not a number")
    x = np.array([tick[field] for tick in ticks], np.float64).reshape(len(ticks), w)
    lo, hi = limits
    with np.errstate(invalid="ignore", over="ignore"):
        x32 = x.astype(np.float32)
        bad = ~np.isfinite(x) | (np.abs(x) > MAX_ABS) | (x32 < lo) | (x32 > hi)
    if bad.any():
        t, i = (int(j) for j in np.argwhere(bad)[0])
        v = float(x[t, i])
        if not math.isfinite(v):
            why = "is not finite"
        elif abs(v) > MAX_ABS:
            why = f"is beyond +-{MAX_ABS:g}"
        else:
            why = f"is outside its bounds [{float(lo[i]):g}, {float(hi[i]):g}]"
        fail(f"episode {e}, tick {t}: {key}[{i}] ({names[i]}) = {show(v)} {why}")
    return x


def arm_target_rows(ticks, objects, e):
    """The episode's arm targets as [ticks, 1]: integers 0 (home) .. len(objects)."""
    rows = []
    for t, tick in enumerate(ticks):
        if "arm_target" not in tick:
            fail(f"episode {e}, tick {t}: no 'arm_target'")
        v = tick["arm_target"]
        if kind_of(v) != "integer":
            fail(f"episode {e}, tick {t}: action.arm_target is {article(kind_of(v))} ({show(v)}), "
                 f"not an integer category")
        if not 0 <= v <= len(objects):
            fail(f"episode {e}, tick {t}: action.arm_target = {show(v)} is not a category "
                 f"(0 home, 1..{len(objects)} the objects)")
        rows.append([v])
    return rows


def read_demos(d):
    """Check every key, type and value of a demos.json; the features, the action bounds, fps and
    per episode its columns, or the first problem refused."""
    if not isinstance(d, dict):
        fail(f"demos.json is {article(kind_of(d))}, not an object")
    instruction = need(d, "instruction", "string", "demos.json")
    if not 1 <= len(instruction) <= MAX_TEXT:
        fail(f"demos.json: instruction has {len(instruction)} characters (1 to {MAX_TEXT})")
    names = need_strings(d, "action_names", "demos.json", 1, MAX_NAMES)
    bounds = action_bounds(d, names)
    config = need(d, "config", "object", "demos.json")
    dt = need(config, "dt_s", "number", "demos.json: config")
    fps = 1.0 / dt if dt > 0 else math.inf
    if not (math.isfinite(fps) and abs(fps - round(fps)) < 1e-6 and 1 <= round(fps) <= 1000):
        fail(f"demos.json: config: dt_s {show(dt)} is not 1 / an integer rate (1 to 1000 Hz)")
    demos = need(d, "demos", "array", "demos.json")
    if not 1 <= len(demos) <= MAX_EPISODES:
        fail(f"demos.json: {len(demos)} demonstrations (1 to {MAX_EPISODES})")
    if not isinstance(demos[0], dict):
        fail(f"episode 0 is {article(kind_of(demos[0]))}, not an object")
    feats = features_of(d, demos[0])
    objects = demos[0]["objects"]
    inf = np.float32(np.inf)
    limits = {"action": (np.asarray(bounds["min"], np.float32), np.asarray(bounds["max"], np.float32))}
    episodes = []
    frames = 0
    for e, demo in enumerate(demos):
        if not isinstance(demo, dict):
            fail(f"episode {e} is {article(kind_of(demo))}, not an object")
        where = f"episode {e}"
        for k in ["objects", "visual_names"]:
            if need(demo, k, "array", where) != demos[0][k]:
                fail(f"{where}: other {k} than episode 0's")
        seed = need(demo, "seed", "integer", where)
        trial = need(demo, "trial", "integer", where)
        if not (0 <= seed <= MAX_SEED and 0 <= trial <= MAX_SEED):
            fail(f"{where}: seed {seed} or trial {trial} is not in 0..2^63-1")
        success = need(demo, "success", "boolean", where)
        ticks = need(demo, "ticks", "array", where)
        frames += len(ticks)
        if not ticks or frames > MAX_FRAMES:
            fail(f"{where}: {len(ticks)} ticks (at least 1, at most {MAX_FRAMES} frames in all)")
        for t, tick in enumerate(ticks):
            if not isinstance(tick, dict):
                fail(f"{where}, tick {t} is {article(kind_of(tick))}, not an object")
        cols = {}
        for field, key, dtype, fnames in feats:
            if dtype == "int64":
                cols[key] = arm_target_rows(ticks, objects, e)
            else:
                lim = limits.get(key, (np.full(len(fnames), -inf), np.full(len(fnames), inf)))
                cols[key] = float_rows(ticks, field, key, fnames, e, lim)
        episodes.append({"seed": seed, "trial": trial, "success": success, "cols": cols})
    return feats, bounds, int(round(fps)), episodes, frames


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
    return pa.FixedSizeListArray.from_arrays(pa.array(flat), dim)


def tables(d, robot_type):
    """The dataset's files as (relative path, pyarrow table or JSON value), all in memory."""
    feats, bounds, fps, demos, frames = read_demos(d)
    instruction = d["instruction"]
    objects = d["demos"][0]["objects"]
    # Frame columns, all episodes in one file (the loader globs data/*/*.parquet).
    ts, frame_index, episode_index, index = [], [], [], []
    episodes = []
    start = 0
    for e, demo in enumerate(demos):
        n = len(demo["cols"]["action"])
        ts += [k / fps for k in range(n)]
        frame_index += list(range(n))
        episode_index += [e] * n
        index += list(range(start, start + n))
        ep = {
            "episode_index": e,
            "tasks": [instruction],
            "length": n,
            "data/chunk_index": 0,
            "data/file_index": 0,
            "dataset_from_index": start,
            "dataset_to_index": start + n,
            "meta/episodes/chunk_index": 0,
            "meta/episodes/file_index": 0,
            "seed": demo["seed"],
            "trial": demo["trial"],
            "success": demo["success"],
        }
        per = {key: stats_of(rows) for key, rows in demo["cols"].items()}
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

    cols = {key: np.concatenate([np.asarray(demo["cols"][key]) for demo in demos])
            for _, key, _, _ in feats}
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
    features[schema.ARM_TARGET]["categories"] = ["home"] + list(objects)
    features[schema.ACTION]["bounds"] = bounds
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
    files = [
        (DATA_PATH.format(chunk_index=0, file_index=0), data),
        (EPISODES_PATH, pa.table(ep_arrays)),
        ("meta/tasks.parquet", tasks_table(instruction)),
        ("meta/info.json", info),
        ("meta/stats.json", {k: {s: v.tolist() for s, v in st.items()} for k, st in stats.items()}),
    ]
    return files, len(demos), frames


def replaceable(out):
    """Whether --out may be written: missing, an empty directory or a dataset directory."""
    if not os.path.lexists(out):
        return True
    if os.path.islink(out) or not os.path.isdir(out):
        return False
    entries = set(os.listdir(out))
    return not entries or (entries <= DATASET_ENTRIES and os.path.isfile(os.path.join(out, "meta", "info.json")))


def write(files, out):
    """Write the files into a new directory beside out, then rename it to out (an existing
    dataset there is replaced only once the new one is complete)."""
    out = os.path.normpath(out)
    if not replaceable(out):
        fail(f"--out {out}: exists and is neither an empty directory nor a dataset (meta/info.json "
             f"and only {', '.join(e + '/' for e in sorted(DATASET_ENTRIES))} at its top); not touched")
    parent = os.path.dirname(os.path.abspath(out))
    os.makedirs(parent, exist_ok=True)
    tmp = tempfile.mkdtemp(prefix=f".{os.path.basename(out)}.", suffix=".tmp", dir=parent)
    old = None
    try:
        for rel, content in files:
            path = os.path.join(tmp, rel)
            os.makedirs(os.path.dirname(path), exist_ok=True)
            if isinstance(content, pa.Table):
                pq.write_table(content, path)
            else:
                with open(path, "w") as f:
                    json.dump(content, f, indent=4, allow_nan=False)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o777 & ~umask)
        if os.path.lexists(out):
            old = tempfile.mkdtemp(prefix=f".{os.path.basename(out)}.", suffix=".old", dir=parent)
            os.rename(out, os.path.join(old, "dataset"))
        os.rename(tmp, out)
        tmp = None
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
            if old is not None:
                os.rename(os.path.join(old, "dataset"), out)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)


class Parser(argparse.ArgumentParser):
    def error(self, message):
        fail(message)


def main(argv=None):
    ap = Parser(description=__doc__.split("\n")[0])
    ap.add_argument("--demos", required=True, help="demos.json of `unitac-lab demos`")
    ap.add_argument("--out", required=True, help="the dataset's root directory")
    ap.add_argument("--robot-type", default="unitac_sim_two_finger")
    try:
        a = ap.parse_args(argv)
        try:
            size = os.path.getsize(a.demos)
            if size > MAX_BYTES:
                fail(f"{a.demos}: {size} bytes (at most {MAX_BYTES})")
            with open(a.demos, encoding="utf-8") as f:
                d = json.load(f)
        except (ValueError, RecursionError) as e:
            fail(f"{a.demos}: not JSON: {str(e).splitlines()[0] if str(e) else type(e).__name__}")
        files, n, frames = tables(d, a.robot_type)
        write(files, a.out)
    except Refused as e:
        msg = " ".join(str(e).split("\n"))
        print(f"lerobot_dataset: {msg}", file=sys.stderr)
        return 1
    except OSError as e:
        print(f"lerobot_dataset: {e.filename or a.out}: {e.strerror or e}", file=sys.stderr)
        return 1
    except MemoryError:
        print("lerobot_dataset: out of memory", file=sys.stderr)
        return 1
    print(f"{n} episodes, {frames} frames of '{' '.join(d['instruction'].splitlines())}' in {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
