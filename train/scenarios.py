"""Scenario variants for the training / held-out renders.

The shipped scenarios (sim/scenarios/*.toml) each have one altitude, one
gimbal pitch and (mostly) the default sea. For a detector that must work
across altitudes and sea states, every (scenario, seed) pair gets a variant
with, drawn from ``random.Random(f"{name}/{seed}")``:

* altitude scaled by a log-uniform factor in [0.6, 2.5] (also the
  ``altitude_profile``), clamped to [12, 160] m;
* gimbal pitch shifted by up to +-10 deg (kept within [25, 90]);
* sea state: wave height 0.1-2.0 m, wave length 3-15 m, random wave and sun
  directions, sun elevation 15-75 deg, glint 0.1-1.0, sea colour jitter.

Objects, paths, events and faults stay the scenario's; the seed also drives
all of the simulator's own random processes (spawn positions, motion, waves).

Usage: python scenarios.py --sim-dir ../sim/scenarios --name calm_baseline --seed 3 --out v.toml --frames 40
(prints the ``--every N`` that gives about ``--frames`` frames over the scenario's duration)
"""

from __future__ import annotations

import argparse
import math
import random
import tomllib
from pathlib import Path


def vary(doc: dict, name: str, seed: int) -> dict:
    rng = random.Random(f"{name}/{seed}")
    doc = dict(doc)
    doc["seed"] = seed
    factor = math.exp(rng.uniform(math.log(0.6), math.log(2.5)))
    drone = dict(doc["drone"])
    clamp_alt = lambda a: round(min(160.0, max(12.0, a * factor)), 1)  # noqa: E731
    drone["altitude_m"] = clamp_alt(drone.get("altitude_m", 30.0))
    if "altitude_profile" in drone:
        drone["altitude_profile"] = [[t, clamp_alt(a)] for t, a in drone["altitude_profile"]]
    doc["drone"] = drone
    gimbal = dict(doc.get("gimbal", {}))
    gimbal["pitch_deg"] = round(min(90.0, max(25.0, gimbal.get("pitch_deg", 45.0) + rng.uniform(-10, 10))), 1)
    doc["gimbal"] = gimbal
    sea = dict(doc.get("sea", {}))
    colour = sea.get("color_rgb", [22, 70, 92])
    sea.update(
        wave_height_m=round(rng.uniform(0.1, 2.0), 2),
        wave_length_m=round(rng.uniform(3.0, 15.0), 1),
        wave_direction_deg=round(rng.uniform(0, 360), 1),
        wave_speed_mps=round(rng.uniform(0.5, 3.0), 2),
        sun_elevation_deg=round(rng.uniform(15, 75), 1),
        sun_azimuth_deg=round(rng.uniform(0, 360), 1),
        glint=round(rng.uniform(0.1, 1.0), 2),
        color_rgb=[int(min(255, max(0, c + rng.randint(-15, 15)))) for c in colour],
    )
    doc["sea"] = sea
    doc["description"] = f"{doc.get('description', name)} (training variant, seed {seed})"
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
    _table(out, None, doc)
    return "\n".join(out) + "\n"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sim-dir", required=True, help="folder of the shipped scenario TOML files")
    ap.add_argument("--name", required=True)
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--frames", type=int, default=40, help="frames wanted per sequence")
    args = ap.parse_args()
    doc = tomllib.loads((Path(args.sim_dir) / f"{args.name}.toml").read_text())
    Path(args.out).write_text(dumps(vary(doc, args.name, args.seed)))
    total = doc["duration_s"] * doc.get("camera", {}).get("fps", 30.0)
    print(max(1, round(total / args.frames)))


if __name__ == "__main__":
    main()
