"""Scenario variants for the training and held-out renders.

The shipped scenarios (sim/scenarios/*.toml) each have one altitude, one
gimbal pitch and (mostly) the default sea. For a detector that must work
across altitudes, sea states and light, every (scenario, seed) pair gets a
variant drawn from ``random.Random(f"{name}/{seed}")``:

* altitude 10-150 m (log-uniform; the scenario's ``altitude_profile`` is
  scaled with it), gimbal pitch shifted by up to +-15 deg within 30-90 deg
  below the horizon;
* sea state (wave height, length, direction, speed), sun elevation and
  azimuth, glint strength and sea colour;
* one to three extra groups of objects (all five classes, rarer ones more
  often) near the scenario's own objects, so every class is seen in every
  condition.

Three conditions are **held out** of training (the ``train`` and ``heldout``
splits never draw them; the ``conditions`` split draws exactly one of them
per variant, in turn):

=========  ==========================  ===========================
condition  training / held-out seeds   held-out conditions
=========  ==========================  ===========================
sea        wave height 0.1-1.5 m       1.5-2.0 m (rough sea)
sun        sun elevation 25-75 deg     12-25 deg (low sun)
altitude   10-80 m and 100-150 m       80-100 m
=========  ==========================  ===========================

Objects, paths, events and faults stay the scenario's; the seed also drives
all of the simulator's own random processes (spawn positions, motion, waves,
looks of the objects, camera effects).

Usage:
  python scenarios.py --sim-dir ../sim/scenarios --name calm_baseline --seed 3 --split train --out v.toml --frames 40
  (prints the ``--every N`` that gives about ``--frames`` frames over the scenario's duration)
  python scenarios.py manifest --data data/sim --out manifest.json
"""

from __future__ import annotations

import argparse
import json
import math
import random
import sys
import tomllib
from pathlib import Path

HELD_OUT = ("sea", "sun", "altitude")
ALT_RANGE = (10.0, 150.0)
ALT_HELD_OUT = (80.0, 100.0)
WAVE_TRAIN, WAVE_HELD_OUT = (0.1, 1.5), (1.5, 2.0)
SUN_TRAIN, SUN_HELD_OUT = (25.0, 75.0), (12.0, 25.0)
EXTRA_CLASSES = ["swimmer", "boat", "jetski", "life_saving_appliance", "buoy"]
EXTRA_WEIGHTS = [2.0, 0.7, 1.2, 1.6, 1.6]


def held_out_condition(name: str, seed: int) -> str:
    """The one condition a ``conditions``-split variant of (name, seed) draws from its held-out range."""
    return HELD_OUT[(sum(map(ord, name)) + seed) % len(HELD_OUT)]


def _altitude(rng: random.Random, held_out: bool) -> float:
    if held_out:
        return rng.uniform(ALT_HELD_OUT[0], ALT_HELD_OUT[1] - 0.1)
    while True:
        a = math.exp(rng.uniform(math.log(ALT_RANGE[0]), math.log(ALT_RANGE[1])))
        if not ALT_HELD_OUT[0] <= a < ALT_HELD_OUT[1]:
            return a


def vary(doc: dict, name: str, seed: int, split: str = "train") -> dict:
    """The variant of scenario ``doc`` for ``seed``; ``split`` is train, heldout or conditions."""
    rng = random.Random(f"{name}/{seed}")
    cond = held_out_condition(name, seed) if split == "conditions" else None
    doc = dict(doc)
    doc["seed"] = seed
    drone = dict(doc["drone"])
    base = float(drone.get("altitude_m", 30.0))
    target = _altitude(rng, cond == "altitude")
    factor = target / base
    lo, hi = (ALT_HELD_OUT if cond == "altitude" else ALT_RANGE)
    clamp_alt = lambda a: round(min(hi, max(lo, a * factor)), 1)  # noqa: E731
    drone["altitude_m"] = round(target, 1)
    if "altitude_profile" in drone:
        prof = [[t, clamp_alt(a)] for t, a in drone["altitude_profile"]]
        if cond != "altitude":
            # Profiles that pass through the held-out band: keep the band out of training frames.
            prof = [[t, a if not ALT_HELD_OUT[0] <= a < ALT_HELD_OUT[1] else (ALT_HELD_OUT[0] - 1 if a < 90 else ALT_HELD_OUT[1])] for t, a in prof]
        drone["altitude_profile"] = prof
    doc["drone"] = drone
    gimbal = dict(doc.get("gimbal", {}))
    gimbal["pitch_deg"] = round(min(90.0, max(30.0, gimbal.get("pitch_deg", 45.0) + rng.uniform(-15, 15))), 1)
    doc["gimbal"] = gimbal
    sea = dict(doc.get("sea", {}))
    colour = sea.get("color_rgb", [22, 70, 92])
    sea.update(
        wave_height_m=round(rng.uniform(*(WAVE_HELD_OUT if cond == "sea" else WAVE_TRAIN)), 2),
        wave_length_m=round(rng.uniform(3.0, 15.0), 1),
        wave_direction_deg=round(rng.uniform(0, 360), 1),
        wave_speed_mps=round(rng.uniform(0.5, 3.0), 2),
        sun_elevation_deg=round(rng.uniform(*(SUN_HELD_OUT if cond == "sun" else SUN_TRAIN)), 1),
        sun_azimuth_deg=round(rng.uniform(0, 360), 1),
        glint=round(rng.uniform(0.1, 1.0), 2),
        color_rgb=[int(min(255, max(0, c + rng.randint(-20, 20)))) for c in colour],
    )
    doc["sea"] = sea
    groups = [dict(g) for g in doc.get("objects", [])]
    centres = [g["spawn_center_ne_m"] for g in groups if "spawn_center_ne_m" in g]
    if centres:
        for _ in range(rng.randint(1, 3)):
            cls = rng.choices(EXTRA_CLASSES, EXTRA_WEIGHTS)[0]
            c = rng.choice(centres)
            groups.append(
                {
                    "class": cls,
                    "count": rng.randint(1, 4) if cls == "swimmer" else rng.randint(1, 2),
                    "spawn_center_ne_m": [round(c[0] + rng.uniform(-25, 25), 1), round(c[1] + rng.uniform(-25, 25), 1)],
                    "spawn_radius_m": 8.0,
                }
            )
        doc["objects"] = groups
    tag = f"held-out condition: {cond}" if cond else f"{split} variant"
    doc["description"] = f"{doc.get('description', name)} ({tag}, seed {seed})"
    doc["_variant"] = {"scenario": name, "seed": seed, "split": split, "held_out_condition": cond}
    return doc


# ------------------------------------------------------------ a small TOML writer
def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v)} as TOML")


def _table(out: list[str], header: str | None, table: dict) -> None:
    scalars = {k: v for k, v in table.items() if not isinstance(v, dict) and not _is_table_array(v)}
    if header is not None:
        out.append(f"\n[{header}]")
    out.extend(f"{k} = {_value(v)}" for k, v in scalars.items())
    for k, v in table.items():
        name = k if header is None else f"{header}.{k}"
        if isinstance(v, dict):
            _table(out, name, v)
        elif _is_table_array(v):
            for item in v:
                out.append(f"\n[[{name}]]")
                sub = []
                _table(sub, None, item)
                out.extend(sub)


def _is_table_array(v) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


def dumps(doc: dict) -> str:
    out: list[str] = []
    meta = doc.get("_variant")
    if meta:
        out.append("# variant: " + json.dumps(meta, sort_keys=True))
    _table(out, None, {k: v for k, v in doc.items() if k != "_variant"})
    return "\n".join(out) + "\n"


def manifest(data: Path) -> dict:
    """What was rendered: per split, each sequence's variant parameters and frame count."""
    out = {}
    for split_dir in sorted(p for p in data.iterdir() if p.is_dir() and p.name != "scenarios"):
        seqs = []
        for seq in sorted(p for p in split_dir.iterdir() if (p / "annotations.json").is_file()):
            toml_path = data / "scenarios" / f"{seq.name}.toml"
            variant = {}
            if toml_path.is_file():
                text = toml_path.read_text()
                first = text.splitlines()[0] if text else ""
                if first.startswith("# variant: "):
                    variant = json.loads(first[len("# variant: "):])
                doc = tomllib.loads(text)
                variant.update(
                    altitude_m=doc["drone"].get("altitude_m"),
                    gimbal_pitch_deg=doc.get("gimbal", {}).get("pitch_deg"),
                    wave_height_m=doc["sea"].get("wave_height_m"),
                    sun_elevation_deg=doc["sea"].get("sun_elevation_deg"),
                    object_groups=[(g["class"], g.get("count", 1)) for g in doc.get("objects", [])],
                )
            ann = json.loads((seq / "annotations.json").read_text())
            cats = {c["id"]: c["name"] for c in ann["categories"]}
            boxes: dict[str, int] = {}
            for a in ann["annotations"]:
                boxes[cats[a["category_id"]]] = boxes.get(cats[a["category_id"]], 0) + 1
            seqs.append({"sequence": seq.name, "frames": len(ann["images"]), "boxes": boxes, **variant})
        out[split_dir.name] = {"sequences": seqs, "frames": sum(s["frames"] for s in seqs)}
    return out


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "manifest":
        ap = argparse.ArgumentParser(prog="scenarios.py manifest")
        ap.add_argument("--data", required=True, type=Path)
        ap.add_argument("--out", required=True, type=Path)
        args = ap.parse_args(sys.argv[2:])
        args.out.write_text(json.dumps(manifest(args.data), indent=1))
        return
    ap = argparse.ArgumentParser()
    ap.add_argument("--sim-dir", required=True, help="folder of the shipped scenario TOML files")
    ap.add_argument("--name", required=True)
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--split", default="train", choices=["train", "heldout", "conditions"])
    ap.add_argument("--out", required=True)
    ap.add_argument("--frames", type=int, default=40, help="frames wanted per sequence")
    args = ap.parse_args()
    doc = tomllib.loads((Path(args.sim_dir) / f"{args.name}.toml").read_text())
    Path(args.out).write_text(dumps(vary(doc, args.name, args.seed, args.split)))
    total = doc["duration_s"] * doc.get("camera", {}).get("fps", 30.0)
    print(max(1, round(total / args.frames)))


if __name__ == "__main__":
    main()
