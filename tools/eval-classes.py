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

The held-out frames' class maps (`stemd-detect --class-out`) are scored
per pixel of the annotated vegetation too (`stemd-eval --classes`: crop
and weed recall, balanced accuracy).

  tools/eval-classes.py [--data DIR] [--out DIR] [--folds N] [--split interleaved|blocks] [--seed N]
                        [--only SET] [--reuse-models] [--set K=V]... [--tools DIR]
  tools/eval-classes.py --train SET_DIR --test SET_DIR [--gsd MM] [--out DIR] [--seed N] [--split ...]
                        [--set K=V]...

The first form takes every set in DATA_DIR with crop/weed annotations:
a CWFID layout (images/, masks/, annotations/; 0.11 mm/px) or a recording
with a class column (frames.csv; 0.25 mm/px, carrot-dev's). The second
trains one model on all of TRAIN (stemd-train) and scores it on TEST, a
set it never saw (say CWFID's test split, or other photos of the same
field), each of the two in either layout; --gsd overrides the layout's.
With --split blocks, every model's own cross-validation (stemd-train
--split blocks, which fits its class-map bar) folds consecutive frames too.

Needs python3-opencv, python3-numpy and python3-yaml (Debian), and the
Release tools. A measurement, not part of stemd: the per-plant figures in
the README's crop-or-weed section come from it.
"""
import argparse
import csv
import json
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


def config_args(gsd):
    return ["--config", os.path.join(HERE, "..", "config", "stemd.yaml"), "--set", f"camera.gsd_mm_per_px={gsd}"]


def class_maps_score(tools, class_dir, recording, log):
    """stemd-eval --classes' JSON for the class maps in class_dir."""
    with open(log, "w") as err:
        result = subprocess.run([os.path.join(tools, "stemd-eval"), "--classes", class_dir, recording, "--json"],
                                stdout=subprocess.PIPE, stderr=err, text=True)
    if result.returncode != 0:
        sys.exit(f"eval-classes: stemd-eval --classes {class_dir} {recording} exited {result.returncode}, see {log}")
    return json.loads(result.stdout)


def report(name, what, rows, model_stems, blind_stems, plants_of, inside, pixels):
    with_model = score(rows, model_stems, plants_of, inside)
    weed_targets = sum(c == "weed" for stems in model_stems.values() for (_, _, c) in stems)
    blind = score(rows, blind_stems, plants_of, inside)
    pct = lambda n, d: f"{n} of {d} ({100.0 * n / max(d, 1):.1f} %)"
    print(f"{name:12} {len(rows)} frames, {what}: "
          f"crop plants with a weed-classed stem {pct(with_model['crop_weed_stem'], with_model['crop'])}; "
          f"weed plants treated {pct(with_model['weed_treated'], with_model['weed'])} "
          f"with {weed_targets} weed targets, "
          f"class-blind (any stem inside) {pct(blind['weed_any_stem'], blind['weed'])}; "
          f"class map per pixel of vegetation: balanced accuracy {pixels['balanced_accuracy']:.3f} "
          f"(crop recall {pixels['crop_recall']:.3f}, weed recall {pixels['weed_recall']:.3f}, "
          f"not segmented {100.0 * pixels['not_segmented']:.1f} %)")
    sys.stdout.flush()


def evaluate(name, recording, gsd, folds, tools, out, plants_of, inside, reuse_models, detect_sets, train_args,
             blocks=False):
    rows = read_recording(recording)
    # Frame i in fold i mod N, as stemd-train folds; or N runs of
    # consecutive frames, so that a frame's neighbours (the same light and
    # field) are rarely in its model's training frames.
    fold_of = (lambda i: i * folds // len(rows)) if blocks else (lambda i: i % folds)
    config = config_args(gsd)
    model_stems, blind_stems = {}, {}
    class_dir = os.path.join(out, name, "class-maps")
    os.makedirs(class_dir, exist_ok=True)
    for k in range(folds):
        fold = os.path.join(out, name, f"{'block' if blocks else 'fold'}-{k}")
        held_out = [r for i, r in enumerate(rows) if fold_of(i) == k]
        write_recording(os.path.join(fold, "train"), [r for i, r in enumerate(rows) if fold_of(i) != k])
        write_recording(os.path.join(fold, "test"), held_out)
        model = os.path.join(fold, "model.yaml")
        if not (reuse_models and os.path.isfile(model)):
            run([os.path.join(tools, "stemd-train"), "--out", model, *train_args, *config, os.path.join(fold, "train")],
                os.path.join(fold, "train.log"))
        run([os.path.join(tools, "stemd-detect"), *config, *detect_sets, "--set", f"classify.model={model}",
             "--csv", os.path.join(fold, "classes.csv"), "--class-out", class_dir, os.path.join(fold, "test")],
            os.path.join(fold, "detect.log"))
        run([os.path.join(tools, "stemd-detect"), *config, "--csv", os.path.join(fold, "blind.csv"),
             os.path.join(fold, "test")], os.path.join(fold, "blind.log"))
        model_stems.update(detections(os.path.join(fold, "classes.csv")))
        blind_stems.update(detections(os.path.join(fold, "blind.csv")))
    pixels = class_maps_score(tools, class_dir, recording, os.path.join(out, name, "classes-eval.log"))
    split = "blocks of consecutive frames" if blocks else "folds by frame"
    report(name, f"{folds} {split}", rows, model_stems, blind_stems, plants_of, inside, pixels)


def held_out(train, test, tools, out, detect_sets, train_args):
    """One model from all of `train`, scored on every frame of `test`."""
    model = os.path.join(out, "held-out", "model.yaml")
    os.makedirs(os.path.dirname(model), exist_ok=True)
    run([os.path.join(tools, "stemd-train"), "--out", model, *train_args, *config_args(train["gsd"]),
         train["recording"]], os.path.join(out, "held-out", "train.log"))
    config = config_args(test["gsd"])
    class_dir = os.path.join(out, "held-out", "class-maps")
    os.makedirs(class_dir, exist_ok=True)
    classes_csv, blind_csv = (os.path.join(out, "held-out", f) for f in ("classes.csv", "blind.csv"))
    run([os.path.join(tools, "stemd-detect"), *config, *detect_sets, "--set", f"classify.model={model}",
         "--csv", classes_csv, "--class-out", class_dir, test["recording"]], os.path.join(out, "held-out", "detect.log"))
    run([os.path.join(tools, "stemd-detect"), *config, "--csv", blind_csv, test["recording"]],
        os.path.join(out, "held-out", "blind.log"))
    rows = read_recording(test["recording"])
    # stemd-detect names a recording's frames by their frames.csv paths,
    # which read_recording() made absolute.
    absolute = lambda stems: {os.path.normpath(os.path.join(test["recording"], k)): v for k, v in stems.items()}
    pixels = class_maps_score(tools, class_dir, test["recording"], os.path.join(out, "held-out", "classes-eval.log"))
    report(test["name"], f"a model from {train['name']}'s {len(read_recording(train['recording']))} frames",
           rows, absolute(detections(classes_csv)), absolute(detections(blind_csv)), test["plants_of"],
           test["inside"], pixels)


def annotated_set(path, out, tools, gsd=None):
    """How to read a set with crop/weed annotations, by its layout: a dict
    with name, recording (with a class column), gsd, plants_of and inside;
    None when `path` holds neither layout."""
    name = os.path.basename(os.path.normpath(path))
    if all(os.path.isdir(os.path.join(path, d)) for d in ("images", "masks", "annotations")):
        recording = os.path.join(out, f"{name}-recording")
        env = dict(os.environ, STEMD_CLASSMAP=os.path.join(tools, "stemd-classmap"))
        subprocess.run([os.path.join(HERE, "cwfid-recording.sh"), path, recording], check=True,
                       stdout=subprocess.DEVNULL, env=env)
        return {"name": name, "recording": recording, "gsd": gsd or 0.11,
                "plants_of": lambda row: cwfid_plants(path, row["rgb"]),
                "inside": lambda plant, x, y: inside_polygon(plant[1], x, y)}
    frames = os.path.join(path, "frames.csv")
    if not os.path.isfile(frames):
        return None
    with open(frames, newline="") as f:
        if not any(row.get("class") for row in csv.DictReader(f)):
            return None
    gsd = gsd or 0.25
    cache = {}

    def class_plants(row):
        if row["class"] not in cache:
            cache.clear()
            cache[row["class"]] = class_image_plants(row["class"], gsd)
        return cache[row["class"]]

    def inside_region(plant, x, y):
        labels = plant[1]
        xi, yi = int(round(x)), int(round(y))
        return 0 <= yi < labels.shape[0] and 0 <= xi < labels.shape[1] and labels[yi, xi] == plant[2]

    return {"name": name, "recording": os.path.abspath(path), "gsd": gsd, "plants_of": class_plants,
            "inside": inside_region}


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
    parser.add_argument("--only", metavar="SET", help="evaluate the set of this name in DATA_DIR only")
    parser.add_argument("--split", choices=["interleaved", "blocks"], default="interleaved",
                        help="folds: frame i in fold i mod N (interleaved, as stemd-train folds) or N runs of "
                             "consecutive frames (blocks: neighbouring frames, alike in light and field, "
                             "stay on one side; stemd-train --split blocks for each model's own folds too)")
    parser.add_argument("--train", metavar="SET_DIR", help="train one model on this set (with --test)")
    parser.add_argument("--test", metavar="SET_DIR", help="score that model on this set (with --train)")
    parser.add_argument("--gsd", type=float, help="mm per pixel of --train and --test (default: the layout's)")
    args = parser.parse_args()
    train_args = ["--seed", str(args.seed)] if args.seed is not None else []
    # Each model's own cross-validation, which fits its class-map bar, split alike.
    if args.split == "blocks":
        train_args += ["--split", "blocks"]
    detect_sets = [a for kv in args.set for a in ("--set", kv)]
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    if bool(args.train) != bool(args.test):
        parser.error("--train and --test go together")
    if args.train:
        sets = []
        for path in (args.train, args.test):
            found = annotated_set(os.path.abspath(path), out, args.tools, args.gsd)
            if found is None:
                parser.error(f"{path} holds neither CWFID's layout (images/, masks/, annotations/) "
                             f"nor a recording with a class column")
            sets.append(found)
        held_out(sets[0], sets[1], args.tools, out, detect_sets, train_args)
        return 0

    data = os.path.abspath(args.data)
    if not os.path.isdir(data):
        print(f"eval-classes: {data} is absent: no real frames to evaluate", file=sys.stderr)
        return 77
    found = 0
    for entry in sorted(os.listdir(data)):
        if args.only not in (None, entry):
            continue
        annotated = annotated_set(os.path.join(data, entry), out, args.tools)
        if annotated is None:
            continue
        found += 1
        evaluate(annotated["name"], annotated["recording"], annotated["gsd"], args.folds, args.tools, out,
                 annotated["plants_of"], annotated["inside"], args.reuse_models, detect_sets, train_args,
                 args.split == "blocks")
    if not found:
        print(f"eval-classes: no set with crop/weed annotations in {data}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
