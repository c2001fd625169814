"""The contact circle of each ball press of a real-frame set (tests/real/*/), annotated here by one
stated rule, with a review picture for a person to check it against the frames.

The rule: for a ball pressed into an elastic gel, the gel's surface follows the ball inside the
contact (its slope grows outward, as r / R) and relaxes back to flat outside it (the slope falls);
the slope is largest at the contact edge (Hertz contact of a sphere on an elastic half-space:
K. L. Johnson, Contact Mechanics, Cambridge University Press, 1985, section 4.2). A GelSight
image's colour is a function of the surface normal (photometric stereo), and its difference to
the background grows with the slope, so along each ray from the press's centre the largest
difference marks the contact edge, whatever the light's direction on that ray. A circle fitted
to those edge points (72 rays, outliers rejected) is the annotation.

  python -m unitac_tools.annotate_presses SET_DIR [--review PNG]
  python -m unitac_tools.annotate_presses SET_DIR --overlays DIR --sheet PNG NN.png...

SET_DIR holds background.png, the presses NN.png and source.json (the set's provenance and, where
the source labelled its presses, their circles). It writes SET_DIR/annotations.json: per press
the circle (x, y, r in pixels), how many rays agreed, and the source's circle beside it. With
--overlays it draws instead the annotated circles onto `unitac contact --overlay`'s pictures
(scripts/real-frames).
"""
import argparse
import glob
import json
import os

import numpy as np
from PIL import Image, ImageDraw

RAYS = 72
# Half-width of the neighbourhood a marker dot is darker than, px (dots are 5-15 px across).
MARKER_WINDOW = 15
# Rays run from 2 px out to this share of the image's shorter side.
MAX_RADIUS_SHARE = 0.35


def read_rgb(path):
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.float64)


def difference(frame, background):
    """|frame - background| over the channels, less the frame's global offset (the median
    difference per channel: an exposure or white-balance drift), 3 x 3 box mean."""
    d = frame - background
    d -= np.median(d.reshape(-1, 3), axis=0)
    return box_mean(np.sqrt((d ** 2).sum(-1)), 1)


def box_mean(a, radius):
    """Box mean of radius `radius` (a (2 radius + 1) square), edges padded."""
    k = 2 * radius + 1
    p = np.pad(a, radius, mode="edge")
    c = np.pad(p.cumsum(0).cumsum(1), ((1, 0), (1, 0)))
    h, w = a.shape
    return (c[k:k + h, k:k + w] - c[:h, k:k + w] - c[k:k + h, :w] + c[:h, :w]) / (k * k)


def marker_mask(frame, background):
    """The printed marker dots of a gel that has them: pixels darker than 0.7 of their
    neighbourhood's mean in the frame or in the background (a dot moves with the gel), grown by
    2 px so that the 3 x 3 mean of the difference leaves no trace of them."""
    dark = np.zeros(frame.shape[:2], bool)
    for im in (frame, background):
        lum = im.mean(-1)
        dark |= lum < 0.7 * box_mean(lum, MARKER_WINDOW)
    return box_mean(dark.astype(np.float64), 2) > 0


def fit_circle(points):
    """Least-squares circle through points (Kasa): (x, y, r)."""
    x, y = points[:, 0], points[:, 1]
    a = np.c_[2 * x, 2 * y, np.ones(len(x))]
    c = np.linalg.lstsq(a, x ** 2 + y ** 2, rcond=None)[0]
    return c[0], c[1], float(np.sqrt(c[2] + c[0] ** 2 + c[1] ** 2))


def edge_points(mag, cx, cy):
    """On each ray from (cx, cy), the point of the largest difference (none where the ray leaves
    the image too soon or the largest is at its end)."""
    h, w = mag.shape
    r_max = MAX_RADIUS_SHARE * min(h, w)
    radii = np.arange(2.0, r_max, 0.5)
    pts = []
    for t in np.linspace(0.0, 2 * np.pi, RAYS, endpoint=False):
        x = cx + radii * np.cos(t)
        y = cy + radii * np.sin(t)
        inside = (x >= 0) & (x <= w - 1) & (y >= 0) & (y <= h - 1)
        if inside.sum() < 20:
            continue
        xs, ys = x[inside], y[inside]
        v = mag[np.round(ys).astype(int), np.round(xs).astype(int)]
        if np.isnan(v).all():
            continue
        k = int(np.nanargmax(v))
        if k < len(v) - 1:
            pts.append((xs[k], ys[k]))
    return np.array(pts)


def annotate(frame, background, markers=False):
    """The press's contact circle: {x, y, r, rays_kept, rays}. With `markers`, the marker dots
    (`marker_mask`) are left out: a moved dot's difference is the largest of any."""
    mag = difference(frame, background)
    if markers:
        mag[marker_mask(frame, background)] = np.nan
    # Start at the centroid of the strongest difference.
    ys, xs = np.nonzero(mag > 0.5 * np.nanpercentile(mag, 99))
    wts = mag[ys, xs]
    cx, cy = (xs * wts).sum() / wts.sum(), (ys * wts).sum() / wts.sum()
    r, kept, pts = 0.0, np.zeros(0, bool), np.zeros((0, 2))
    for _ in range(3):
        pts = edge_points(mag, cx, cy)
        if len(pts) < 8:
            raise ValueError(f"{len(pts)} rays found an edge, 8 are needed")
        kept = np.ones(len(pts), bool)
        for _ in range(3):
            cx, cy, r = fit_circle(pts[kept])
            res = np.abs(np.hypot(pts[:, 0] - cx, pts[:, 1] - cy) - r)
            kept = res < max(2.0, 2.5 * float(np.median(res[kept])))
    return {"x": round(float(cx), 2), "y": round(float(cy), 2), "r": round(r, 2),
            "rays_kept": int(kept.sum()), "rays": int(len(pts))}


def save_sheet(tiles, path):
    """The tiles (one size), 3 a row, to `path`: a JPEG at quality 92 where the path says so (a
    quarter of the PNG's bytes, for a picture committed beside a README; 256 colours lost the
    gel's shading), else a PNG."""
    tw, th = tiles[0].size
    rows = (len(tiles) + 2) // 3
    sheet = Image.new("RGB", (3 * tw, rows * th))
    for i, t in enumerate(tiles):
        sheet.paste(t, ((i % 3) * tw, (i // 3) * th))
    if path.lower().endswith((".jpg", ".jpeg")):
        sheet.save(path, quality=92)
    else:
        sheet.save(path)


def review(set_dir, entries, path):
    """One tile per press: the frame and its difference (x3 around grey), the annotation in red
    and the source's circle in green; 3 presses a row."""
    bg = read_rgb(os.path.join(set_dir, "background.png"))
    tiles = []
    for e in entries:
        im = read_rgb(os.path.join(set_dir, e["file"]))
        diff = np.clip((im - bg) * 3 + 128, 0, 255)
        t = Image.fromarray(np.concatenate([im, diff], 1).astype(np.uint8))
        d = ImageDraw.Draw(t)
        w = im.shape[1]
        for off in (0, w):
            for c, colour in ((e.get("source"), (0, 255, 0)), (e, (255, 0, 0))):
                if c:
                    d.ellipse([c["x"] - c["r"] + off, c["y"] - c["r"],
                               c["x"] + c["r"] + off, c["y"] + c["r"]], outline=colour)
        d.text((4, 4), e["file"], fill=(255, 255, 0))
        tiles.append(t)
    save_sheet(tiles, path)


def overlay_sheet(set_dir, overlay_dir, files, path):
    """`unitac contact --overlay`'s pictures of `files` (in `overlay_dir`: the frame with the
    contact region's outline in red and its centroid, and beside it the depth map with the
    depth's contact outline where there is a depth model), each with its annotated circle drawn
    in green on every panel, 3 a row."""
    with open(os.path.join(set_dir, "annotations.json")) as f:
        circles = {c["file"]: c for c in json.load(f)["presses"]}
    with Image.open(os.path.join(set_dir, "background.png")) as bg:
        panel = bg.width
    tiles = []
    for name in files:
        c = circles[name]
        stem = os.path.splitext(name)[0]
        t = Image.open(os.path.join(overlay_dir, f"{stem}.overlay.png")).convert("RGB")
        d = ImageDraw.Draw(t)
        for off in range(0, t.width - panel + 1, panel):
            d.ellipse([c["x"] - c["r"] + off, c["y"] - c["r"], c["x"] + c["r"] + off,
                       c["y"] + c["r"]], outline=(0, 255, 0))
        d.text((4, 4), name, fill=(255, 255, 0))
        tiles.append(t)
    save_sheet(tiles, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("set_dir")
    ap.add_argument("--review", help="write the review sheet (PNG) here")
    ap.add_argument("--overlays", help="instead: the directory of `unitac contact --overlay`'s "
                    "pictures of the set's presses, drawn with their annotated circles into "
                    "--sheet")
    ap.add_argument("--sheet", help="with --overlays: the PNG to write")
    ap.add_argument("files", nargs="*", help="with --overlays: the presses to draw (NN.png)")
    a = ap.parse_intermixed_args()
    if a.overlays:
        if not a.sheet or not a.files:
            ap.error("--overlays needs --sheet and the presses to draw")
        overlay_sheet(a.set_dir, a.overlays, a.files, a.sheet)
        print(f"{a.sheet}: {len(a.files)} presses")
        return
    with open(os.path.join(a.set_dir, "source.json")) as f:
        source = json.load(f)
    labels = {c["file"]: c for c in source.get("labels", [])}
    bg = read_rgb(os.path.join(a.set_dir, "background.png"))
    entries = []
    for path in sorted(glob.glob(os.path.join(a.set_dir, "[0-9]*.png"))):
        name = os.path.basename(path)
        e = {"file": name, **annotate(read_rgb(path), bg, bool(source.get("markers")))}
        if name in labels:
            e["source"] = {k: labels[name][k] for k in ("x", "y", "r")}
        entries.append(e)
    out = {
        "rule": "contact edge = largest difference to the background along each of 72 rays "
                "from the press's centre (the slope is largest at a Hertz contact's edge); "
                "circle fitted to those points (python -m unitac_tools.annotate_presses)",
        "presses": entries,
    }
    with open(os.path.join(a.set_dir, "annotations.json"), "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")
    if a.review:
        review(a.set_dir, entries, a.review)
    print(f"{a.set_dir}: {len(entries)} presses annotated")


if __name__ == "__main__":
    main()
