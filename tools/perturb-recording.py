#!/usr/bin/python3
"""A copy of a recording as another light or a noisier sensor would give it.

Every frame's rgb (and nir) image is rewritten as PNG (lossless, so the
perturbation is the only change):
  --exposure K    every 8-bit value times K (0.25: two stops darker for a
                  linear output; the frames' gamma makes the light's change
                  larger still), rgb and nir alike;
  --gains B,G,R   each colour channel times its gain: a colour cast of the
                  light or of the white balance (nir untouched);
  --vignetting C  the lens's natural falloff, cos^4 of the field angle,
                  scaled so the frame's corners get C of the centre's light
                  (0.5: one stop darker at the corners), rgb and nir alike;
  --motion-blur-px L
                  the travel during the exposure: each value the mean of L
                  pixels along the image's columns (the direction of travel
                  for camera.forward up or down), on the stored values, rgb
                  and nir alike;
  --noise-dn S    Gaussian noise of S digital numbers added after the
                  scaling, as a sensor's read and gain noise: at a lower
                  exposure the same S is a larger share of the signal;
  --yuyv          the rgb frame as a V4L2 camera's YUYV (4:2:2) gives it:
                  BT.601 limited-range Y, U, V, each horizontal pair of
                  pixels sharing the mean of their U and V, decoded by
                  OpenCV's COLOR_YUV2BGR_YUYV as stemd's V4L2 source does;
  --jpeg-quality Q
                  last, the frame encoded as a camera's MJPEG stream
                  would be (OpenCV's JPEG at quality Q, colour at half
                  resolution: 4:2:0) and decoded again.
Values are rounded and saturated to 8 bits. Masks, class maps and every
other column are kept (paths made absolute), so stemd-eval --iou and
stemd-detect run on the copy as on the original.

  tools/perturb-recording.py SRC_RECORDING DST_DIR [--exposure K]
                             [--gains B,G,R] [--vignetting C]
                             [--motion-blur-px L] [--noise-dn S] [--yuyv]
                             [--jpeg-quality Q] [--seed N]

Needs python3-opencv and python3-numpy (Debian).
"""
import argparse
import csv
import os
import sys

import cv2
import numpy as np


def gains(text):
    parts = text.split(",")
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f"{text}: three gains B,G,R")
    values = [float(p) for p in parts]
    if any(v < 0 for v in values):
        raise argparse.ArgumentTypeError(f"{text}: gains are not negative")
    return values


def falloff(shape, corner):
    """Relative illumination over a frame: cos^4 of the field angle, the
    angle's tangent growing linearly with the distance from the centre,
    with the value at the corners `corner`."""
    height, width = shape[:2]
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    half_diagonal = np.hypot((width - 1) / 2.0, (height - 1) / 2.0)
    rho2 = ((x - (width - 1) / 2.0) ** 2 + (y - (height - 1) / 2.0) ** 2) / max(half_diagonal, 1.0) ** 2
    # cos^4(atan(t)) = 1 / (1 + t^2)^2, with t^2 = a rho^2 and (1 + a)^-2 = corner.
    a = 1.0 / np.sqrt(corner) - 1.0
    return (1.0 / (1.0 + a * rho2) ** 2).astype(np.float32)


def through_yuyv(bgr):
    """An 8-bit BGR frame through a camera's YUYV: BT.601 limited range, the
    chroma of each horizontal pair of pixels averaged, then OpenCV's decoder.
    An odd last column has no pair and is kept as it was."""
    f = bgr.astype(np.float32)
    b, g, r = f[..., 0], f[..., 1], f[..., 2]
    y = 16 + (65.481 * r + 128.553 * g + 24.966 * b) / 255
    u = 128 + (-37.797 * r - 74.203 * g + 112.0 * b) / 255
    v = 128 + (112.0 * r - 93.786 * g - 18.214 * b) / 255
    even = bgr.shape[1] - bgr.shape[1] % 2
    packed = np.empty((bgr.shape[0], even, 2), np.uint8)
    packed[..., 0] = np.clip(np.rint(y[:, :even]), 0, 255)
    packed[:, 0::2, 1] = np.clip(np.rint((u[:, 0:even:2] + u[:, 1:even:2]) / 2), 0, 255)
    packed[:, 1::2, 1] = np.clip(np.rint((v[:, 0:even:2] + v[:, 1:even:2]) / 2), 0, 255)
    out = bgr.copy()
    out[:, :even] = cv2.cvtColor(packed, cv2.COLOR_YUV2BGR_YUYV)
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("src")
    parser.add_argument("dst")
    parser.add_argument("--exposure", type=float, default=1.0)
    parser.add_argument("--gains", type=gains, default=[1.0, 1.0, 1.0])
    parser.add_argument("--vignetting", type=float, default=1.0)
    parser.add_argument("--motion-blur-px", type=int, default=1)
    parser.add_argument("--noise-dn", type=float, default=0.0)
    parser.add_argument("--yuyv", action="store_true")
    parser.add_argument("--jpeg-quality", type=int, default=0)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    if args.exposure < 0 or args.noise_dn < 0:
        parser.error("--exposure and --noise-dn are not negative")
    if not 0 < args.vignetting <= 1:
        parser.error("--vignetting is the corners' share of the centre's light, in (0, 1]")
    if args.motion_blur_px < 1:
        parser.error("--motion-blur-px is a length in pixels, at least 1")
    if args.jpeg_quality and not 1 <= args.jpeg_quality <= 100:
        parser.error("--jpeg-quality is in [1, 100] (0: no JPEG)")
    listing = os.path.join(args.src, "frames.csv")
    try:
        with open(listing, newline="") as f:
            reader = csv.DictReader(f)
            columns = reader.fieldnames or []
            rows = list(reader)
    except OSError as e:
        sys.exit(f"perturb-recording: {listing}: {e.strerror}")
    if "rgb" not in columns:
        sys.exit(f"perturb-recording: {listing}: no rgb column")
    os.makedirs(args.dst, exist_ok=True)
    rng = np.random.default_rng(args.seed)

    def source(path):
        return path if os.path.isabs(path) else os.path.join(args.src, path)

    def write(image, scale, name):
        out = image.astype(np.float32) * scale
        if args.vignetting < 1:
            field = falloff(image.shape, args.vignetting)
            out *= field[..., None] if out.ndim == 3 else field
        if args.motion_blur_px > 1:
            kernel = np.full((args.motion_blur_px, 1), 1.0 / args.motion_blur_px, np.float32)
            out = cv2.filter2D(out, -1, kernel, borderType=cv2.BORDER_REPLICATE)
        if args.noise_dn > 0:
            out += rng.normal(0.0, args.noise_dn, out.shape).astype(np.float32)
        values = np.clip(np.rint(out), 0, 255).astype(np.uint8)
        if args.yuyv and values.ndim == 3:
            values = through_yuyv(values)
        if args.jpeg_quality:
            ok, encoded = cv2.imencode(".jpg", values, [cv2.IMWRITE_JPEG_QUALITY, args.jpeg_quality])
            if not ok:
                sys.exit(f"perturb-recording: {name}: cannot encode as JPEG")
            values = cv2.imdecode(encoded, cv2.IMREAD_UNCHANGED)
        path = os.path.join(args.dst, name)
        if not cv2.imwrite(path, values):
            sys.exit(f"perturb-recording: {path}: cannot write")

    def png_name(path, prefix=""):
        return prefix + os.path.splitext(os.path.basename(path))[0] + ".png"

    for row in rows:
        rgb = cv2.imread(source(row["rgb"]), cv2.IMREAD_COLOR)
        if rgb is None:
            sys.exit(f"perturb-recording: {source(row['rgb'])}: cannot read")
        name = png_name(row["rgb"])
        write(rgb, args.exposure * np.array(args.gains, np.float32), name)
        row["rgb"] = name
        if row.get("nir"):
            nir = cv2.imread(source(row["nir"]), cv2.IMREAD_GRAYSCALE)
            if nir is None:
                sys.exit(f"perturb-recording: {source(row['nir'])}: cannot read")
            name = png_name(row["nir"], "nir-")
            write(nir, args.exposure, name)
            row["nir"] = name
        for column in ("mask", "class"):
            if row.get(column):
                row[column] = os.path.abspath(source(row[column]))
    with open(os.path.join(args.dst, "frames.csv"), "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)


if __name__ == "__main__":
    main()
