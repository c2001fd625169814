"""Check a dataset directory against what LeRobot's v3.0 loader (LeRobotDataset in lerobot 0.4.x,
src/lerobot/datasets/lerobot_dataset.py and utils.py) reads, with pyarrow alone.

usage: check_lerobot_v3.py ROOT

What the loader does, and what is checked for it:
- load_info: meta/info.json; `codebase_version` must parse as v3.x (check_version_compatibility);
  every feature has dtype, shape, names; `fps`, `chunks_size`, `data_files_size_in_mb`,
  `video_files_size_in_mb` positive; `data_path` formats with chunk_index/file_index; the
  five index features (timestamp float32, frame_index, episode_index, index, task_index int64,
  shape [1]) are declared; totals agree with the files.
- load_tasks: pandas.read_parquet(meta/tasks.parquet), looked up by its index (the task text):
  the pandas metadata must name `__index_level_0__` as the index; task_index 0..n-1.
- load_episodes: every meta/episodes/*/*.parquet; the columns it indexes (episode_index, tasks,
  length, data/chunk_index, data/file_index, dataset_from_index, dataset_to_index) and
  stats/<feature>/{min,max,mean,std,count} for every feature.
- load_hf_dataset: every data/*/*.parquet, cast to get_hf_features_from_features(features): a
  shape-[1] feature is a scalar of its dtype, a shape-[n] one a list of n of its dtype; no
  other column. __getitem__ reads index, episode_index, task_index, timestamp per frame.
- load_stats: meta/stats.json, per feature min/max/mean/std of the feature's shape, count [1].
Beyond the loader: frames are ordered (index = row, frame_index 0..length-1, timestamp =
frame_index / fps within LeRobot's tolerance_s 1e-4), every float finite; a feature with `bounds`
({min, max} per value) has every value inside them (compared as the float32 stored), one with
`categories` every value an index into them.
Exit 0 and one summary line, or exit 1 and one line per problem.
"""
import glob
import json
import math
import os
import re
import sys

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

INDEX_FEATURES = {"timestamp": "float32", "frame_index": "int64", "episode_index": "int64",
                  "index": "int64", "task_index": "int64"}
EPISODE_COLUMNS = {"episode_index": pa.int64(), "length": pa.int64(),
                   "data/chunk_index": pa.int64(), "data/file_index": pa.int64(),
                   "dataset_from_index": pa.int64(), "dataset_to_index": pa.int64()}
STATS = ["min", "max", "mean", "std", "count"]
TOLERANCE_S = 1e-4
ARROW = {"float32": pa.float32(), "float64": pa.float64(), "int64": pa.int64(),
         "int32": pa.int32(), "bool": pa.bool_(), "string": pa.string()}


class Problems:
    def __init__(self):
        self.items = []

    def check(self, ok, msg):
        if not ok:
            self.items.append(msg)
        return ok


def check_info(root, p):
    info = json.load(open(os.path.join(root, "meta", "info.json")))
    m = re.fullmatch(r"v(\d+)\.(\d+)", str(info.get("codebase_version", "")))
    p.check(m is not None and m.group(1) == "3",
            f"info.json: codebase_version {info.get('codebase_version')!r} is not v3.x")
    for k in ["fps", "chunks_size", "data_files_size_in_mb", "video_files_size_in_mb"]:
        p.check(isinstance(info.get(k), int) and info[k] > 0, f"info.json: {k} must be a positive int")
    for k in ["total_episodes", "total_frames", "total_tasks"]:
        p.check(isinstance(info.get(k), int) and info[k] >= 0, f"info.json: {k} missing")
    try:
        info["data_path"].format(chunk_index=0, file_index=0)
    except (KeyError, AttributeError, IndexError, ValueError) as e:
        p.check(False, f"info.json: data_path does not format: {e}")
    feats = info.get("features", {})
    for key, ft in feats.items():
        ok = p.check(all(k in ft for k in ["dtype", "shape", "names"]),
                     f"info.json: feature {key} lacks dtype, shape or names")
        if ok and ft["dtype"] not in ("video", "image"):
            p.check(ft["dtype"] in ARROW, f"info.json: feature {key}: dtype {ft['dtype']}")
            p.check(isinstance(ft["shape"], list) and len(ft["shape"]) == 1 and ft["shape"][0] >= 1,
                    f"info.json: feature {key}: shape {ft['shape']} (vectors only here)")
            if ft["names"] is not None:
                p.check(len(ft["names"]) == ft["shape"][0],
                        f"info.json: feature {key}: {len(ft['names'])} names for shape {ft['shape']}")
            if "bounds" in ft:
                b = ft["bounds"]
                n = ft["shape"][0] if isinstance(ft["shape"], list) and ft["shape"] else 0
                ok = isinstance(b, dict) and all(
                    isinstance(b.get(k), list) and len(b[k]) == n
                    and all(type(v) in (int, float) and math.isfinite(v) for v in b[k]) for k in ["min", "max"])
                p.check(ok and all(lo < hi for lo, hi in zip(b["min"], b["max"])),
                        f"info.json: feature {key}: bounds are not finite min < max lists of {n}")
            if "categories" in ft:
                c = ft["categories"]
                p.check(isinstance(c, list) and c and all(isinstance(v, str) for v in c)
                        and ft["dtype"] == "int64",
                        f"info.json: feature {key}: categories are not a list of names of an int64 feature")
    for key, dtype in INDEX_FEATURES.items():
        p.check(key in feats and feats[key].get("dtype") == dtype and feats[key].get("shape") == [1],
                f"info.json: index feature {key} ({dtype}, [1]) not declared")
    if any(ft.get("dtype") == "video" for ft in feats.values()):
        p.check(isinstance(info.get("video_path"), str), "info.json: video features without video_path")
    return info


def check_tasks(root, p):
    t = pq.read_table(os.path.join(root, "meta", "tasks.parquet"))
    meta = json.loads((t.schema.metadata or {}).get(b"pandas", b"{}"))
    idx = meta.get("index_columns", [])
    p.check(idx == ["__index_level_0__"] and "__index_level_0__" in t.column_names,
            "tasks.parquet: the task text is not the pandas index (__index_level_0__)")
    p.check(t.schema.field("task_index").type == pa.int64(), "tasks.parquet: task_index is not int64")
    tasks = t.column("__index_level_0__").to_pylist() if "__index_level_0__" in t.column_names else []
    p.check(len(set(tasks)) == len(tasks) and all(isinstance(s, str) and s for s in tasks),
            "tasks.parquet: task texts must be distinct, non-empty strings")
    p.check(sorted(t.column("task_index").to_pylist()) == list(range(t.num_rows)),
            "tasks.parquet: task_index is not 0..n-1")
    return dict(zip(tasks, t.column("task_index").to_pylist()))


def check_episodes(root, info, tasks, p):
    paths = sorted(glob.glob(os.path.join(root, "meta", "episodes", "*", "*.parquet")))
    if not p.check(paths, "meta/episodes: no parquet file"):
        return None
    ep = pa.concat_tables([pq.read_table(x) for x in paths])
    for c, ty in EPISODE_COLUMNS.items():
        p.check(c in ep.column_names and ep.schema.field(c).type == ty,
                f"episodes: column {c} missing or not {ty}")
    p.check("tasks" in ep.column_names and pa.types.is_list(ep.schema.field("tasks").type),
            "episodes: tasks is not a list of strings")
    for key, ft in info["features"].items():
        for s in STATS:
            p.check(f"stats/{key}/{s}" in ep.column_names, f"episodes: stats/{key}/{s} missing")
    if p.items:
        return None
    rows = ep.select(list(EPISODE_COLUMNS) + ["tasks"]).to_pylist()
    p.check([r["episode_index"] for r in rows] == list(range(len(rows))),
            "episodes: episode_index is not 0..n-1 in order")
    p.check(len(rows) == info["total_episodes"], "info.json: total_episodes disagrees with episodes")
    at = 0
    for r in rows:
        e = r["episode_index"]
        p.check(r["dataset_from_index"] == at and r["dataset_to_index"] - r["dataset_from_index"] == r["length"],
                f"episodes: episode {e}: from/to/length not contiguous")
        at = r["dataset_to_index"]
        p.check(all(t in tasks for t in r["tasks"]) and r["tasks"], f"episodes: episode {e}: unknown task")
        path = os.path.join(root, info["data_path"].format(chunk_index=r["data/chunk_index"],
                                                           file_index=r["data/file_index"]))
        p.check(os.path.exists(path), f"episodes: episode {e}: data file {path} missing")
        for key, ft in info["features"].items():
            n = ft["shape"][0]
            for s in STATS:
                v = ep.column(f"stats/{key}/{s}")[e].as_py()
                want = 1 if s == "count" else n
                p.check(isinstance(v, list) and len(v) == want,
                        f"episodes: episode {e}: stats/{key}/{s} is not {want} long")
            cnt = ep.column(f"stats/{key}/count")[e].as_py()
            p.check(cnt == [r["length"]], f"episodes: episode {e}: stats/{key}/count != length")
    p.check(at == info["total_frames"], "info.json: total_frames disagrees with episodes")
    return rows


def check_data(root, info, tasks, rows, p):
    paths = sorted(glob.glob(os.path.join(root, "data", "*", "*.parquet")))
    if not p.check(paths, "data: no parquet file"):
        return 0
    data = pa.concat_tables([pq.read_table(x) for x in paths])
    feats = {k: v for k, v in info["features"].items() if v["dtype"] not in ("video", "image")}
    p.check(set(data.column_names) == set(feats),
            f"data: columns {sorted(set(data.column_names) ^ set(feats))} differ from the features")
    for key, ft in feats.items():
        if key not in data.column_names:
            continue
        ty = data.schema.field(key).type
        want = ARROW.get(ft["dtype"])
        n = ft["shape"][0]
        if n == 1:
            p.check(ty == want, f"data: {key} is {ty}, the loader casts to scalar {want}")
        else:
            ok = (pa.types.is_fixed_size_list(ty) and ty.list_size == n) or pa.types.is_list(ty)
            p.check(ok and ty.value_type == want, f"data: {key} is {ty}, the loader wants a list of {n} {want}")
            if ok and pa.types.is_list(ty):
                lens = set(pa.compute.list_value_length(data.column(key)).to_pylist())
                p.check(lens == {n}, f"data: {key} has rows of lengths {sorted(lens)}, not {n}")
        if ft["dtype"].startswith("float"):
            col = data.column(key)
            vals = col.combine_chunks().flatten() if n > 1 else col
            arr = np.asarray(vals.to_numpy(zero_copy_only=False), np.float64)
            p.check(np.isfinite(arr).all(), f"data: {key} has values that are not finite")
            if "bounds" in ft and not p.items:
                x = np.asarray(arr, np.float32).reshape(-1, n)
                lo = np.asarray(ft["bounds"]["min"], np.float64).astype(np.float32)
                hi = np.asarray(ft["bounds"]["max"], np.float64).astype(np.float32)
                bad = np.argwhere((x < lo) | (x > hi))
                if len(bad):
                    row, i = (int(j) for j in bad[0])
                    name = ft["names"][i] if ft["names"] else i
                    p.check(False, f"data: frame {row}: {key}[{i}] ({name}) = {float(x[row, i]):g} is outside "
                                   f"its bounds [{float(lo[i]):g}, {float(hi[i]):g}] "
                                   f"({len(bad)} values out of bounds)")
        if "categories" in ft and not p.items:
            v = data.column(key).to_numpy()
            bad = np.flatnonzero((v < 0) | (v >= len(ft["categories"])))
            if len(bad):
                p.check(False, f"data: frame {int(bad[0])}: {key} = {int(v[bad[0]])} is not one of its "
                               f"{len(ft['categories'])} categories ({len(bad)} frames)")
    if p.items:
        return 0
    p.check(data.num_rows == info["total_frames"], "data: rows != total_frames")
    idx = data.column("index").to_numpy()
    p.check((idx == np.arange(data.num_rows)).all(), "data: index is not the row number")
    ep = data.column("episode_index").to_numpy()
    fi = data.column("frame_index").to_numpy()
    ts = data.column("timestamp").to_numpy().astype(np.float64)
    ti = data.column("task_index").to_numpy()
    p.check(set(ti.tolist()) <= set(tasks.values()), "data: task_index not in tasks.parquet")
    for r in rows or []:
        a, b, e = r["dataset_from_index"], r["dataset_to_index"], r["episode_index"]
        p.check((ep[a:b] == e).all(), f"data: rows {a}..{b} are not all episode {e}")
        p.check((fi[a:b] == np.arange(b - a)).all(), f"data: episode {e}: frame_index is not 0..length-1")
        p.check(np.abs(ts[a:b] - fi[a:b] / info["fps"]).max(initial=0) <= TOLERANCE_S,
                f"data: episode {e}: timestamps are not frame_index / fps")
    return data.num_rows


def check_stats(root, info, p):
    stats = json.load(open(os.path.join(root, "meta", "stats.json")))
    for key, ft in info["features"].items():
        if not p.check(key in stats, f"stats.json: {key} missing"):
            continue
        s = stats[key]
        for k in STATS:
            v = np.asarray(s.get(k, []), np.float64)
            want = (1,) if k == "count" else tuple(ft["shape"])
            p.check(v.shape == want and np.isfinite(v).all(), f"stats.json: {key}/{k} is not finite {want}")
        if all(np.asarray(s.get(k, [])).shape == tuple(ft["shape"]) for k in ["min", "mean", "max"]):
            lo, mu, hi = (np.asarray(s[k], np.float64) for k in ["min", "mean", "max"])
            p.check((lo <= mu + 1e-6 * (1 + abs(mu))).all() and (mu <= hi + 1e-6 * (1 + abs(mu))).all(),
                    f"stats.json: {key}: mean outside [min, max]")


def main(argv):
    if len(argv) != 2:
        print(__doc__.split("\n")[2], file=sys.stderr)
        return 2
    root = argv[1]
    p = Problems()
    try:
        info = check_info(root, p)
        tasks = check_tasks(root, p)
        rows = check_episodes(root, info, tasks, p) if not p.items else None
        frames = check_data(root, info, tasks, rows, p) if not p.items else 0
        if not p.items:
            check_stats(root, info, p)
    except (OSError, KeyError, ValueError, TypeError, pa.ArrowException) as e:
        p.check(False, f"{type(e).__name__}: {e}")
    if p.items:
        for m in p.items:
            print(m)
        return 1
    print(f"ok: v3.0, {info['total_episodes']} episodes, {frames} frames, "
          f"{len(info['features'])} features, {len(tasks)} task(s), fps {info['fps']}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
