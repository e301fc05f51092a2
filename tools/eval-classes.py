#!/usr/bin/python3
"""Crop or weed per annotated plant, as the robot would treat them:
`stemd-detect --csv` with a model that never saw the frame, scored
against the human annotation of each plant.

For each set, frames are split into folds by frame (frame i in fold
i mod N, as `stemd-train` splits them); each fold's frames are run through
`stemd-detect` with a model `stemd-train` made from the other folds, and
once without a model (the class-blind detector). Then, per annotated plant:
  - a crop plant "gets a weed-classed stem" when a stem reported inside it
    is classed weed (it would be stamped under scheduler.policy weeds_only);
  - a weed plant is "treated" when a stem reported inside it is classed
    weed; class-blind, when any stem is reported inside it;
  - "weed targets" counts the stems classed weed over the held-out frames:
    the strikes "weeds only" would command (classify.weed_cover_radius_mm
    adds some).
A plant is an annotated polygon on CWFID (annotations/NNN_annotation.yaml;
polygons may overlap, a stem inside two counts for both) and a connected
region of one class in the class image on a recording with a class column,
of at least 10 mm² (carrot-dev: touching plants of one class are one
plant there).

  tools/eval-classes.py [--data DIR] [--out DIR] [--folds N] [--seed N] [--only SET] [--reuse-models]
                        [--set K=V]... [--tools DIR]

Needs python3-opencv, python3-numpy and python3-yaml (Debian), and the
Release tools. A measurement, not part of stemd: the per-plant figures in
the README's crop-or-weed section come from it.
"""
import argparse
import csv
import os
import subprocess
import sys

import cv2
import numpy as np
import yaml

HERE = os.path.dirname(os.path.abspath(__file__))
# A class image's regions smaller than this are no plant to stemd either
# (plants.min_area_mm2's default); carrot-dev's class images hold thousands
# of such specks along the outlines.
MIN_REGION_MM2 = 10.0


def read_recording(directory):
    """frames.csv rows with every path made absolute."""
    with open(os.path.join(directory, "frames.csv"), newline="") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        for key in ("rgb", "nir", "mask", "class"):
            if row.get(key):
                row[key] = os.path.normpath(os.path.join(directory, row[key]))
    return rows


def write_recording(directory, rows):
    os.makedirs(directory, exist_ok=True)
    with open(os.path.join(directory, "frames.csv"), "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        writer.writeheader()
        writer.writerows(rows)


def run(cmd, log):
    with open(log, "w") as out:
        result = subprocess.run(cmd, stdout=out, stderr=subprocess.STDOUT)
    if result.returncode != 0:
        sys.exit(f"eval-classes: {' '.join(cmd)} exited {result.returncode}, see {log}")


def detections(path):
    """{image: [(x, y, class)]} from a stemd-detect --csv file."""
    stems = {}
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            stems.setdefault(row["image"], []).append(
                (float(row["x"]), float(row["y"]), row.get("class", "unknown")))
    return stems


def cwfid_plants(data, rgb):
    """[(kind, polygon)] of one CWFID frame from its annotation YAML."""
    number = os.path.basename(rgb).split("_")[0]
    with open(os.path.join(data, "annotations", f"{number}_annotation.yaml")) as f:
        annotation = yaml.safe_load(f)
    plants = []
    for plant in annotation.get("annotation", []):
        xs, ys = plant["points"]["x"], plant["points"]["y"]
        if not isinstance(xs, list):   # a one-point "polygon"
            xs, ys = [xs], [ys]
        polygon = np.array(list(zip(xs, ys)), np.float32).reshape(-1, 1, 2)
        plants.append((plant["type"], polygon))
    return plants


def inside_polygon(polygon, x, y):
    return len(polygon) >= 3 and cv2.pointPolygonTest(polygon, (x, y), False) >= 0


def class_image_plants(class_path, gsd):
    """[(kind, label image, label)] for the connected regions of each class
    of at least MIN_REGION_MM2."""
    image = cv2.imread(class_path, cv2.IMREAD_GRAYSCALE)
    min_px = MIN_REGION_MM2 / (gsd * gsd)
    plants = []
    for value, kind in ((1, "crop"), (2, "weed")):
        count, labels, stats, _ = cv2.connectedComponentsWithStats((image == value).astype(np.uint8), connectivity=8)
        for label in range(1, count):
            if stats[label, cv2.CC_STAT_AREA] >= min_px:
                plants.append((kind, labels, label))
    return plants


def score(rows, stems_by_image, plants_of, inside):
    """Counts per annotated plant for one run's stems."""
    counts = {"crop": 0, "weed": 0, "crop_weed_stem": 0, "weed_treated": 0, "weed_any_stem": 0}
    for row in rows:
        stems = stems_by_image.get(row["rgb"], [])
        for plant in plants_of(row):
            kind = plant[0]
            classes = [c for (x, y, c) in stems if inside(plant, x, y)]
            counts[kind] += 1
            if kind == "crop":
                counts["crop_weed_stem"] += "weed" in classes
            else:
                counts["weed_treated"] += "weed" in classes
                counts["weed_any_stem"] += bool(classes)
    return counts


def evaluate(name, recording, gsd, folds, tools, out, plants_of, inside, reuse_models, detect_sets, train_args):
    rows = read_recording(recording)
    config = ["--config", os.path.join(HERE, "..", "config", "stemd.yaml"),
              "--set", f"camera.gsd_mm_per_px={gsd}"]
    model_stems, blind_stems = {}, {}
    for k in range(folds):
        fold = os.path.join(out, name, f"fold-{k}")
        held_out = [r for i, r in enumerate(rows) if i % folds == k]
        write_recording(os.path.join(fold, "train"), [r for i, r in enumerate(rows) if i % folds != k])
        write_recording(os.path.join(fold, "test"), held_out)
        model = os.path.join(fold, "model.yaml")
        if not (reuse_models and os.path.isfile(model)):
            run([os.path.join(tools, "stemd-train"), "--out", model, *train_args, *config, os.path.join(fold, "train")],
                os.path.join(fold, "train.log"))
        run([os.path.join(tools, "stemd-detect"), *config, *detect_sets, "--set", f"classify.model={model}",
             "--csv", os.path.join(fold, "classes.csv"), os.path.join(fold, "test")],
            os.path.join(fold, "detect.log"))
        run([os.path.join(tools, "stemd-detect"), *config, "--csv", os.path.join(fold, "blind.csv"),
             os.path.join(fold, "test")], os.path.join(fold, "blind.log"))
        model_stems.update(detections(os.path.join(fold, "classes.csv")))
        blind_stems.update(detections(os.path.join(fold, "blind.csv")))
    with_model = score(rows, model_stems, plants_of, inside)
    weed_targets = sum(c == "weed" for stems in model_stems.values() for (_, _, c) in stems)
    blind = score(rows, blind_stems, plants_of, inside)
    pct = lambda n, d: f"{n} of {d} ({100.0 * n / max(d, 1):.1f} %)"
    print(f"{name:12} {len(rows)} frames, {folds} folds by frame: "
          f"crop plants with a weed-classed stem {pct(with_model['crop_weed_stem'], with_model['crop'])}; "
          f"weed plants treated {pct(with_model['weed_treated'], with_model['weed'])} "
          f"with {weed_targets} weed targets, "
          f"class-blind (any stem inside) {pct(blind['weed_any_stem'], blind['weed'])}")
    sys.stdout.flush()


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", default=os.path.join(HERE, "..", "..", "shared", "data"))
    parser.add_argument("--out", default=os.path.join(HERE, "..", "out", "eval-classes"))
    parser.add_argument("--folds", type=int, default=5)
    parser.add_argument("--reuse-models", action="store_true",
                        help="keep the fold models an earlier run left in --out (same frames and folds)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="a configuration override for the runs with a model, e.g. classify.weed_confidence=0.75")
    parser.add_argument("--tools", default=os.path.join(HERE, "..", "build", "release", "tools"))
    parser.add_argument("--seed", type=int,
                        help="stemd-train's seed for the forests (default: its own): a forest's random draws "
                             "move these counts, so compare changes over several seeds")
    parser.add_argument("--only", choices=["cwfid-train", "carrot-dev"], help="evaluate one set only")
    args = parser.parse_args()
    train_args = ["--seed", str(args.seed)] if args.seed is not None else []
    data = os.path.abspath(args.data)
    detect_sets = [a for kv in args.set for a in ("--set", kv)]
    out = os.path.abspath(args.out)
    if not os.path.isdir(data):
        print(f"eval-classes: {data} is absent: no real frames to evaluate", file=sys.stderr)
        return 77

    cwfid = os.path.join(data, "cwfid-train")
    if args.only in (None, "cwfid-train") and os.path.isdir(os.path.join(cwfid, "annotations")):
        recording = os.path.join(out, "cwfid-recording")
        env = dict(os.environ, STEMD_CLASSMAP=os.path.join(args.tools, "stemd-classmap"))
        subprocess.run([os.path.join(HERE, "cwfid-recording.sh"), cwfid, recording], check=True,
                       stdout=subprocess.DEVNULL, env=env)
        evaluate("cwfid-train", recording, 0.11, args.folds, args.tools, out,
                 lambda row: cwfid_plants(cwfid, row["rgb"]),
                 lambda plant, x, y: inside_polygon(plant[1], x, y), args.reuse_models, detect_sets,
                 train_args)
    carrot = os.path.join(data, "carrot-dev")
    if args.only in (None, "carrot-dev") and os.path.isfile(os.path.join(carrot, "frames.csv")):
        cache = {}

        def carrot_plants(row):
            if row["class"] not in cache:
                cache.clear()
                cache[row["class"]] = class_image_plants(row["class"], 0.25)
            return cache[row["class"]]

        def inside_region(plant, x, y):
            labels = plant[1]
            xi, yi = int(round(x)), int(round(y))
            return 0 <= yi < labels.shape[0] and 0 <= xi < labels.shape[1] and labels[yi, xi] == plant[2]

        evaluate("carrot-dev", carrot, 0.25, args.folds, args.tools, out, carrot_plants, inside_region,
                 args.reuse_models, detect_sets,
                 train_args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
