#!/usr/bin/python3
"""Where a vegetation mask loses IoU at the plants' outline, and what other
outline rules would give.

Starts from stemd's thresholded plants (masks written by `stemd-detect
--set segment.edge_radius_px=0 --mask-out DIR`), recomputes stemd's index
(chromatic Excess Green, 3x3 binomial smoothing) and applies, per frame:
  - stemd's mixed-edge step (a pixel within the window of a plant is
    vegetation when its index is more than halfway from the frame's soil
    mode to the mean of the plant pixels in the window, and above the soil
    mode + 2 sigma): the default, which should match stemd's own masks;
  - variants of it: another mixing fraction; after it, the same rule
    again with a local soil level (the mean of the non-plant pixels in the
    window, optionally only those farther than a gap from the plant),
    deciding every pixel with a window or only adding; the luminance's mixing fraction averaged
    with the index's; the edge step on the unsmoothed index, or on the index
    sharpened by a guided filter with the luminance as guide;
  - hysteresis instead: seeds grown through connected pixels above a given
    fraction of the way from the soil mode to the threshold.
Then it prints each rule's mean (min) IoU against the human masks, where
the default rule's errors lie (within 1.5 px of the human outline or
beyond 3.5 px), and the mean IoU of the default masks moved by whole
pixels (an offset between masks and photos shows as a shift that helps).

  tools/outline-rules.py RECORDING SEED_MASK_DIR [--gt-vegetation nonzero|zero]

Needs python3-opencv and python3-numpy (Debian). A measurement, not part of
stemd: figures in the README's real-frame section come from it.
"""
import argparse
import os
import sys

import cv2
import numpy as np
from masked_frames import masked_rows

WINDOW_RADIUS_PX = 5  # segment.edge_radius_px's default


def chromatic_exg(bgr, smooth=True):
    """stemd's index: round(128 + 160 (2G - R - B) / (R + G + B + frame mean)), then 3x3 binomial."""
    b, g, r = [c.astype(np.float32) for c in cv2.split(bgr)]
    s = b + g + r
    mean = max(float(s[::4, ::4].mean()), 1.0)
    raw = np.clip(np.round(128 + 160 * (2 * g - r - b) / (s + mean)), 0, 255).astype(np.int32)
    if not smooth:
        return raw
    p = np.pad(raw, 1, mode="edge")
    rows = p[:-2] + 2 * p[1:-1] + p[2:]
    return (rows[:, :-2] + 2 * rows[:, 1:-1] + rows[:, 2:] + 8) >> 4


def soil_levels(index):
    """The soil mode (3-level smoothed histogram) and mode + 2 sigma of its lower side."""
    h = np.bincount(index.ravel(), minlength=256).astype(float)
    mode = int(np.argmax(h + np.r_[0, h[:-1]] + np.r_[h[1:], 0]))
    v = np.arange(mode + 1)
    sigma = np.sqrt((h[: mode + 1] * (v - mode) ** 2).sum() / max(h[: mode + 1].sum(), 1))
    return mode, int(np.ceil(mode + 2 * sigma))


def box_sum(image, radius):
    k = 2 * radius + 1
    return cv2.boxFilter(image.astype(np.float32), -1, (k, k), normalize=False, borderType=cv2.BORDER_CONSTANT)


def square(radius):
    return np.ones((2 * radius + 1, 2 * radius + 1), np.uint8)


def guided_by_luma(bgr, index, radius, eps):
    """He et al.'s guided filter of the index with the full-resolution
    luminance as the guide: a 4:2:0 JPEG keeps colour at half resolution,
    so a leaf edge is sharp only in the luminance."""
    y = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY).astype(np.float32)
    p = index.astype(np.float32)
    k = (2 * radius + 1, 2 * radius + 1)
    mean_y, mean_p = cv2.blur(y, k), cv2.blur(p, k)
    a = (cv2.blur(y * p, k) - mean_y * mean_p) / (cv2.blur(y * y, k) - mean_y * mean_y + eps)
    b = mean_p - a * mean_y
    return cv2.blur(a, k) * y + cv2.blur(b, k)


def edge_rule(bgr, seeds, fraction=0.5, local_soil=False, soil_gap_px=0, luma_weight=0.0, smooth=True, guide=None):
    index = chromatic_exg(bgr)
    soil, floor = soil_levels(index)
    decide = index if smooth else chromatic_exg(bgr, smooth=False)
    if guide is not None:
        decide = guided_by_luma(bgr, index, *guide)
    r = WINDOW_RADIUS_PX
    plant = seeds.astype(np.float32)
    n_plant = box_sum(plant, r)
    plant_mean = box_sum(decide * plant, r) / np.maximum(n_plant, 1)
    enough = n_plant >= (2 * r + 1) ** 2 // 4
    soil_level = np.full(index.shape, float(soil), np.float32)
    if local_soil or luma_weight:
        far = seeds if soil_gap_px == 0 else cv2.dilate(seeds.astype(np.uint8), square(soil_gap_px)) > 0
        other = (~far).astype(np.float32)
        n_other = box_sum(other, r)
        enough &= n_other >= (2 * r + 1) ** 2 // 8
        if local_soil:
            soil_level = box_sum(decide * other, r) / np.maximum(n_other, 1)
    part = (decide - soil_level) / np.maximum(plant_mean - soil_level, 1)
    if luma_weight:
        y = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY).astype(np.float32)
        y_plant = box_sum(y * plant, r) / np.maximum(n_plant, 1)
        y_other = box_sum(y * other, r) / np.maximum(n_other, 1)
        contrast = y_plant - y_other
        luma_part = (y - y_other) / np.where(np.abs(contrast) < 1, 1, contrast)
        part = np.where(np.abs(contrast) > 10, (1 - luma_weight) * part + luma_weight * luma_part, part)
    grown = enough & (part > fraction) & (index > floor)
    if local_soil:
        # Both ways: the rule decides every pixel it has a window for.
        out = seeds.copy()
        out[enough] = grown[enough]
        return out
    return seeds | grown


def hysteresis(bgr, seeds, fraction):
    index = chromatic_exg(bgr)
    soil, floor = soil_levels(index)
    # stemd's threshold lies just below the faintest pixel of its plants.
    threshold = int(index[seeds].min()) - 1 if seeds.any() else 255
    weak = (index > max(floor, soil + fraction * (threshold - soil))).astype(np.uint8)
    n, labels = cv2.connectedComponents(weak, connectivity=8)
    keep = np.zeros(n, bool)
    keep[np.unique(labels[seeds & (weak > 0)])] = True
    keep[0] = False
    return seeds | keep[labels]


RULES = {
    "stemd's edge step (half leaf, frame soil mode)": lambda bgr, s: edge_rule(bgr, s),
    "seeds only (no edge step)": lambda bgr, s: s,
    "edge step, 0.6 of the way to the leaf": lambda bgr, s: edge_rule(bgr, s, fraction=0.6),
    "edge step, then again with a local soil level (both ways)":
        lambda bgr, s: edge_rule(bgr, edge_rule(bgr, s), local_soil=True),
    "edge step, then again with a local soil level, adding only":
        lambda bgr, s: edge_rule(bgr, s) | edge_rule(bgr, edge_rule(bgr, s), local_soil=True),
    "edge step, then again with a local soil level 2 px from the plant":
        lambda bgr, s: edge_rule(bgr, edge_rule(bgr, s), local_soil=True, soil_gap_px=2),
    "edge step, luminance averaged in": lambda bgr, s: edge_rule(bgr, s, luma_weight=0.5, soil_gap_px=2),
    "edge step on the unsmoothed index": lambda bgr, s: edge_rule(bgr, s, smooth=False),
    "edge step on the index guided by the luminance (1 px, eps 4)": lambda bgr, s: edge_rule(bgr, s, guide=(1, 4.0)),
    "edge step on the index guided by the luminance (1 px, eps 100)": lambda bgr, s: edge_rule(bgr, s, guide=(1, 100.0)),
    "edge step on the index guided by the luminance (2 px, eps 25)": lambda bgr, s: edge_rule(bgr, s, guide=(2, 25.0)),
    "hysteresis at 3/4 of soil mode to threshold": lambda bgr, s: hysteresis(bgr, s, 0.75),
    "hysteresis at 1/2": lambda bgr, s: hysteresis(bgr, s, 0.5),
}


def iou(a, b):
    union = np.count_nonzero(a | b)
    return np.count_nonzero(a & b) / union if union else 1.0


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recording")
    parser.add_argument("seed_masks", help="stemd-detect --mask-out DIR with segment.edge_radius_px=0")
    parser.add_argument("--gt-vegetation", choices=["nonzero", "zero"], default="nonzero")
    args = parser.parse_args()
    rows = masked_rows(args.recording, "outline-rules")
    scores = {name: [] for name in RULES}
    shifts = {(dx, dy): [] for dy in (-1, 0, 1) for dx in (-1, 0, 1)}
    errors = dict(truth=0, fp_near=0, fn_near=0, fp_far=0, fn_far=0)
    for row in rows:
        bgr = cv2.imread(os.path.join(args.recording, row["rgb"]), cv2.IMREAD_COLOR)
        mask = cv2.imread(os.path.join(args.recording, row["mask"]), cv2.IMREAD_GRAYSCALE)
        name = os.path.splitext(os.path.basename(row["rgb"]))[0] + ".png"
        seeds = cv2.imread(os.path.join(args.seed_masks, name), cv2.IMREAD_GRAYSCALE)
        if bgr is None or mask is None or seeds is None or not (bgr.shape[:2] == mask.shape == seeds.shape):
            sys.exit(f"outline-rules: {row['rgb']}: unreadable image, mask or seed mask ({name}), or sizes differ")
        truth = mask > 0 if args.gt_vegetation == "nonzero" else mask == 0
        seeds = seeds > 0
        for rule, apply in RULES.items():
            scores[rule].append(iou(apply(bgr, seeds), truth))
        default = edge_rule(bgr, seeds)
        inside = cv2.distanceTransform(truth.astype(np.uint8), cv2.DIST_L2, 5)
        outside = cv2.distanceTransform((~truth).astype(np.uint8), cv2.DIST_L2, 5)
        to_outline = np.where(truth, inside, outside)
        fp, fn = default & ~truth, truth & ~default
        errors["truth"] += np.count_nonzero(truth)
        errors["fp_near"] += np.count_nonzero(fp & (to_outline <= 1.5))
        errors["fn_near"] += np.count_nonzero(fn & (to_outline <= 1.5))
        errors["fp_far"] += np.count_nonzero(fp & (to_outline > 3.5))
        errors["fn_far"] += np.count_nonzero(fn & (to_outline > 3.5))
        for (dx, dy), values in shifts.items():
            moved = np.roll(default, (dy, dx), axis=(0, 1))
            values.append(iou(moved[2:-2, 2:-2], truth[2:-2, 2:-2]))
    print(f"{len(rows)} frames of {args.recording}: mean (min) IoU per outline rule")
    for rule, values in scores.items():
        print(f"  {np.mean(values):.4f} ({np.min(values):.4f})  {rule}")
    t = max(errors["truth"], 1)
    print("stemd's edge step, wrong area as a share of the human vegetation area:")
    print(f"  within 1.5 px of the human outline: false positives {errors['fp_near'] / t:.3f}, "
          f"false negatives {errors['fn_near'] / t:.3f}")
    print(f"  beyond 3.5 px: false positives {errors['fp_far'] / t:.3f}, false negatives {errors['fn_far'] / t:.3f}")
    print("stemd's edge step moved by (dx, dy) px (2 px border left out): mean IoU")
    for (dx, dy), values in sorted(shifts.items(), key=lambda kv: -np.mean(kv[1])):
        print(f"  ({dx:+d}, {dy:+d})  {np.mean(values):.4f}")


if __name__ == "__main__":
    main()
