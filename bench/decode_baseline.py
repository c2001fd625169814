"""Python baseline for `unitac-lab bench decode`: the GelSight Mini frame pipeline of the vendor SDK
(gsrobotics), as users run it today, timed per frame on the same JPEGs as the Rust decoder.

Pipelines, each ending in the same crop (the fraction per side of the Rust side) and resize to the
output size:
- vendor: cv2.imdecode at full size (3280x2464), crop, cv2.resize (default interpolation, as the
  SDK does);
- the fastest a Python user has today: cv2.imdecode with IMREAD_REDUCED_COLOR_8 / _4
  (libjpeg-turbo's scaled IDCT), and Pillow's Image.draft at 1/8 (also libjpeg-turbo), then crop
  and resize.
Also YUYV and UYVY 320x240 -> RGB with cv2.cvtColor. Single thread (cv2.setNumThreads(1)).

usage: decode_baseline.py DIR N_JPEGS CROP OUT_W OUT_H YUYV_W YUYV_H REPEAT
DIR holds frame_<i>.jpg and yuyv.raw; writes DIR/py_out.raw (frame 0's output, RGB).
prints one JSON object: per-frame wall and CPU times in microseconds.
"""
import json
import sys
import time

import io

import cv2
import numpy as np
from PIL import Image
import PIL


def stats(wall, cpu):
    wall = sorted(wall)
    cpu = sorted(cpu)
    return {
        "median_s": wall[len(wall) // 2],
        "mean_s": sum(wall) / len(wall),
        "cpu_median_s": cpu[len(cpu) // 2],
        "cpu_mean_s": sum(cpu) / len(cpu),
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

    def finish(img):
        h, w = img.shape[:2]
        bx, by = int(round(w * crop)), int(round(h * crop))
        img = img[by:h - by, bx:w - bx]
        return cv2.resize(img, (out_w, out_h))

    def vendor(buf):
        return finish(cv2.imdecode(buf, cv2.IMREAD_COLOR))

    def reduced8(buf):
        return finish(cv2.imdecode(buf, cv2.IMREAD_REDUCED_COLOR_8))

    def reduced4(buf):
        return finish(cv2.imdecode(buf, cv2.IMREAD_REDUCED_COLOR_4))

    blobs = [b.tobytes() for b in jpegs]

    def pillow8(raw):
        im = Image.open(io.BytesIO(raw))
        im.draft("RGB", (im.width // 8, im.height // 8))
        w, h = im.size
        bx, by = int(round(w * crop)), int(round(h * crop))
        return im.crop((bx, by, w - bx, h - by)).resize((out_w, out_h), Image.BILINEAR)

    first = vendor(jpegs[0])
    cv2.cvtColor(first, cv2.COLOR_BGR2RGB).tofile(f"{d}/py_out.raw")

    def timed(f, bufs, rep):
        wall, cpu = [], []
        for _ in range(rep):
            for b in bufs:
                t0, c0 = time.perf_counter(), time.process_time()
                f(b)
                wall.append(time.perf_counter() - t0)
                cpu.append(time.process_time() - c0)
        return stats(wall, cpu)

    out = {
        "mjpeg": timed(vendor, jpegs, repeat),
        "reduced8": timed(reduced8, jpegs, repeat),
        "reduced4": timed(reduced4, jpegs, repeat),
        "pillow_draft8": timed(pillow8, blobs, repeat),
    }
    uyvy = yuyv.reshape(yh, yw // 2, 4)[:, :, [1, 0, 3, 2]].reshape(yh, yw, 2).copy()
    out["yuyv"] = timed(lambda b: cv2.cvtColor(b, cv2.COLOR_YUV2RGB_YUYV), [yuyv], repeat * 50)
    out["uyvy"] = timed(lambda b: cv2.cvtColor(b, cv2.COLOR_YUV2RGB_UYVY), [uyvy], repeat * 50)
    out["numpy"] = np.__version__
    out["opencv"] = cv2.__version__
    out["pillow"] = PIL.__version__
    print(json.dumps(out))


if __name__ == "__main__":
    main()
