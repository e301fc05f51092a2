#!/usr/bin/python3
"""How far can a per-pixel colour rule go on a set with human masks?

For every frame of a recording directory with a `mask` column, the best
global threshold of each colour rule is found *with the frame's own human
mask* (an oracle no real pipeline has), and its IoU is printed; the means
close the table. A rule's oracle is an upper bound for any threshold method
on that rule; the quadratic discriminant, fitted per frame on the frame's own
mask, bounds every colour rule of degree two. What is left above it is
spatial: where the human drew the outline, not what colour the pixels have.

  tools/iou-ceiling.py RECORDING [--gt-vegetation nonzero|zero] [--frames N]

Needs python3-opencv and python3-numpy (Debian).
"""
import argparse
import os
import sys

import cv2
import numpy as np
from masked_frames import masked_rows


def best_threshold_iou(index, truth):
    best = 0.0
    for t in np.quantile(index, np.linspace(0.5, 0.98, 120)):
        predicted = index > t
        union = np.count_nonzero(predicted | truth)
        if union:
            best = max(best, np.count_nonzero(predicted & truth) / union)
    return best


def rules(bgr, truth):
    b, g, r = [c.astype(np.float32) for c in cv2.split(bgr)]
    brightness = b + g + r
    exg = 2 * g - r - b
    mean_brightness = max(float(brightness[::4, ::4].mean()), 1.0)
    out = {
        "ExG (raw)": exg,
        "ExG / (R+G+B) (chromatic)": exg / (brightness + 1.0),
        "ExG / (R+G+B + frame mean) (stemd's chromatic_exg)": exg / (brightness + mean_brightness),
        "-a* (CIELAB)": -cv2.cvtColor(bgr, cv2.COLOR_BGR2LAB)[..., 1].astype(np.float32),
    }
    # Quadratic discriminant of (B, G, R), fitted on this frame's own mask.
    x = np.stack([b, g, r], axis=-1).reshape(-1, 3) / 255.0
    features = np.hstack([x, x ** 2, x[:, [0]] * x[:, [1]], x[:, [1]] * x[:, [2]], x[:, [0]] * x[:, [2]]])
    y = truth.reshape(-1)
    if y.any() and (~y).any():
        spread = np.cov(features[y][::5].T) + np.cov(features[~y][::5].T)
        w = np.linalg.solve(spread + 1e-6 * np.eye(features.shape[1]), features[y].mean(0) - features[~y].mean(0))
        out["quadratic colour, fitted on the frame's own mask"] = (features @ w).reshape(truth.shape)
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recording")
    parser.add_argument("--gt-vegetation", choices=["nonzero", "zero"], default="nonzero")
    parser.add_argument("--frames", type=int, default=0, help="at most this many frames (0: all)")
    args = parser.parse_args()
    rows = masked_rows(args.recording, "iou-ceiling")
    if args.frames:
        rows = rows[: args.frames]
    totals = {}
    for row in rows:
        bgr = cv2.imread(os.path.join(args.recording, row["rgb"]), cv2.IMREAD_COLOR)
        mask = cv2.imread(os.path.join(args.recording, row["mask"]), cv2.IMREAD_GRAYSCALE)
        if bgr is None or mask is None or bgr.shape[:2] != mask.shape:
            sys.exit(f"iou-ceiling: {row['rgb']}: unreadable image or mask, or sizes differ")
        truth = mask > 0 if args.gt_vegetation == "nonzero" else mask == 0
        for name, index in rules(bgr, truth).items():
            totals.setdefault(name, []).append(best_threshold_iou(index, truth))
    print(f"{len(rows)} frames of {args.recording}: mean (min) IoU at each rule's best threshold per frame")
    for name, values in totals.items():
        print(f"  {np.mean(values):.3f} ({np.min(values):.3f})  {name}")


if __name__ == "__main__":
    main()
