"""Python baseline for `unitac bench decode`: the GelSight Mini frame pipeline of the vendor SDK
(gsrobotics), as users run it today, timed per frame on the same JPEGs as the Rust decoder.

Pipeline: cv2.imdecode at full size (3280x2464), crop a border (the same fraction per side as the
Rust side), cv2.resize to the output size (default interpolation, as the SDK). Also YUYV 320x240 ->
RGB with cv2.cvtColor. Single thread (cv2.setNumThreads(1)).

usage: decode_baseline.py DIR N_JPEGS CROP OUT_W OUT_H YUYV_W YUYV_H REPEAT
DIR holds frame_<i>.jpg and yuyv.raw; writes DIR/py_out.raw (frame 0's output, RGB).
prints one JSON object: per-frame wall and CPU times in microseconds.
"""
import json
import sys
import time

import cv2
import numpy as np


def stats(wall, cpu):
    wall = sorted(t * 1e6 for t in wall)
    cpu = sorted(t * 1e6 for t in cpu)
    return {
        "median_us": wall[len(wall) // 2],
        "mean_us": sum(wall) / len(wall),
        "cpu_median_us": cpu[len(cpu) // 2],
        "cpu_mean_us": sum(cpu) / len(cpu),
        "frames": len(wall),
    }


def main():
    d = sys.argv[1]
    n, crop, out_w, out_h, yw, yh, repeat = (
        int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5]),
        int(sys.argv[6]), int(sys.argv[7]), int(sys.argv[8]))
    cv2.setNumThreads(1)
    jpegs = [np.fromfile(f"{d}/frame_{i}.jpg", np.uint8) for i in range(n)]
    yuyv = np.fromfile(f"{d}/yuyv.raw", np.uint8).reshape(yh, yw, 2)

    def pipeline(buf):
        img = cv2.imdecode(buf, cv2.IMREAD_COLOR)
        h, w = img.shape[:2]
        bx, by = int(round(w * crop)), int(round(h * crop))
        img = img[by:h - by, bx:w - bx]
        return cv2.resize(img, (out_w, out_h))

    first = pipeline(jpegs[0])
    cv2.cvtColor(first, cv2.COLOR_BGR2RGB).tofile(f"{d}/py_out.raw")
    wall, cpu = [], []
    for _ in range(repeat):
        for b in jpegs:
            t0, c0 = time.perf_counter(), time.process_time()
            pipeline(b)
            wall.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
    jpeg = stats(wall, cpu)
    wall, cpu = [], []
    for _ in range(repeat * 50):
        t0, c0 = time.perf_counter(), time.process_time()
        cv2.cvtColor(yuyv, cv2.COLOR_YUV2RGB_YUYV)
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    print(json.dumps({
        "mjpeg": jpeg,
        "yuyv": stats(wall, cpu),
        "numpy": np.__version__,
        "opencv": cv2.__version__,
    }))


if __name__ == "__main__":
    main()
