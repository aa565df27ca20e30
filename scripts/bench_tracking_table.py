"""Table of scripts/bench_tracking.sh: reads OUT/<scenario>/<seed>/{run}.json (mgmot eval
--json) and the results files, prints one Markdown table (one row per scenario, seed and run,
the oracle first) and writes OUT/results.json. Standard library only.

ids/obj = distinct predicted ids / distinct true objects (considered ground-truth rows);
rel. = IDF1 relative to the oracle's on the same detections."""
import json
import os
import sys

RUNS = ["oracle", "baseline", "online", "online_withheld", "offline"]


def ids_in(path, considered_only=False):
    ids = set()
    with open(path) as f:
        for line in f:
            p = line.split(",")
            if len(p) < 7:
                continue
            if considered_only and float(p[6]) == 0:
                continue
            ids.add(int(float(p[1])))
    return ids


def detector(seed):
    """Which detector a row's boxes came from: the simulated one, or the shipped model on
    rendered frames (seed folders named <seed>-model)."""
    return "model" if seed.endswith("-model") else "simulated"


def seed_key(s):
    return (s != "default", s)


def main(out):
    rows = []
    for sc in sorted(os.listdir(out)):
        sdir = os.path.join(out, sc)
        if not os.path.isdir(sdir):
            continue
        for seed in sorted(os.listdir(sdir), key=seed_key):
            d = os.path.join(sdir, seed)
            n_true = len(ids_in(os.path.join(d, "gt", "gt", "gt.txt"), considered_only=True))
            oracle_idf1 = None
            for run in RUNS:
                with open(os.path.join(d, run + ".json")) as f:
                    m = json.load(f)
                n_pred = len(ids_in(os.path.join(d, run + ".txt")))
                if run == "oracle":
                    oracle_idf1 = m["IDF1"]
                rows.append({
                    "scenario": sc, "seed": seed, "run": run,
                    "HOTA": m["HOTA"], "AssA": m["AssA"], "IDF1": m["IDF1"], "IDSW": m["IDSW"],
                    "true_objects": n_true, "pred_ids": n_pred,
                    "ids_per_object": n_pred / n_true if n_true else float("nan"),
                    "idf1_vs_oracle": m["IDF1"] / oracle_idf1 if oracle_idf1 else float("nan"),
                })
    with open(os.path.join(out, "results.json"), "w") as f:
        json.dump(rows, f, indent=1)
    # Summary: per scenario and run, the mean over seeds.
    print("Mean over seeds (IDF1/oracle = the run's IDF1 over the oracle's on the same detections):")
    print()
    print("| scenario | detector | seeds | oracle IDF1 | baseline IDF1 | online IDF1 (ids/obj) | online withheld IDF1 (ids/obj) | offline IDF1 (ids/obj) | online / oracle | online withheld / oracle | offline / oracle |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    groups = sorted({(r["scenario"], detector(r["seed"])) for r in rows})
    for sc, det in groups:
        group = [r for r in rows if r["scenario"] == sc and detector(r["seed"]) == det]

        def mean(run, key):
            v = [r[key] for r in group if r["run"] == run]
            return sum(v) / len(v)
        n = len({r["seed"] for r in group})
        print(f"| {sc} | {det} | {n} | {mean('oracle','IDF1'):.3f} | {mean('baseline','IDF1'):.3f} "
              f"| {mean('online','IDF1'):.3f} ({mean('online','ids_per_object'):.2f}) "
              f"| {mean('online_withheld','IDF1'):.3f} ({mean('online_withheld','ids_per_object'):.2f}) "
              f"| {mean('offline','IDF1'):.3f} ({mean('offline','ids_per_object'):.2f}) "
              f"| {mean('online','idf1_vs_oracle'):.2f} | {mean('online_withheld','idf1_vs_oracle'):.2f} "
              f"| {mean('offline','idf1_vs_oracle'):.2f} |")
    print()
    print("Every run:")
    print()
    print("| scenario | seed | run | HOTA | AssA | IDF1 | IDF1/oracle | IDSW | ids/obj |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['scenario']} | {r['seed']} | {r['run']} | {r['HOTA']:.3f} | {r['AssA']:.3f} "
              f"| {r['IDF1']:.3f} | {r['idf1_vs_oracle']:.2f} | {r['IDSW']} | {r['ids_per_object']:.2f} |")


if __name__ == "__main__":
    main(sys.argv[1])
