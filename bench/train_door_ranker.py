#!/usr/bin/python3
"""Train the exit finder's door ranker (the ``ranked`` method) on simulator rooms.

The rooms are ``random_world(seed)`` for the training seeds (default 400-5399), scanned exactly
as ``bench_exit_finder.py`` scans its rooms 0-399 (same scan cache), so that the benchmark scores
the model only on rooms it never saw. Per room the finder's own candidate code
(``finder.ranked_candidates``, from the SLAM map's origin as the ``ranked`` method sees it) gives
the door candidates and their features; a candidate is a positive when its centre lies within
half a door width + 0.3 m of a true exit (the benchmark's hit rule), visible or not.

A scikit-learn ``HistGradientBoostingClassifier`` (fixed random_state; its early stopping holds
out 10 % of the candidates) is fitted on all candidates and written as plain JSON
(``ranker.DoorRanker``). The trees are read from the fitted model's ``_predictors`` and
``_baseline_prediction``, which scikit-learn does not promise to keep: the script checks that the
JSON model gives scikit-learn's own probabilities on every candidate and refuses to write it
otherwise. Deterministic for the same rooms and versions.

Usage: bench/train_door_ranker.py [--seeds 400-5399] [--cache DIR] [--jobs J] [--out FILE]
Default output: src/sparse_nav/exit_finder/door_ranker.json (the model the package ships).
"""
import argparse
import hashlib
import json
import multiprocessing
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.path.join(HERE, "..", "src")
sys.path.insert(0, SRC)
sys.path.insert(0, HERE)

import bench_exit_finder as bench  # noqa: E402
from sparse_nav.exit_finder import ExitFinderConfig, ExitFinderError, prepare  # noqa: E402
from sparse_nav.exit_finder import finder  # noqa: E402
from sparse_nav.exit_finder.ranker import PACKAGED_MODEL, DoorRanker  # noqa: E402

PARAMS = {"max_iter": 300, "max_leaf_nodes": 127, "learning_rate": 0.05, "random_state": 0}


def room_examples(room, cfg):
    """(features, labels) of one scanned room's candidates; None when the cloud holds no room."""
    try:
        prep = prepare(room["points"], "-y", cfg)
    except ExitFinderError:
        return None
    _, doors, x = finder.ranked_candidates(prep, cfg, np.random.default_rng(cfg.seed))
    if not doors:
        return None
    centres = prep.frame.from_norm(np.array([d.centre for d in doors]))
    world = bench.to_world_xy(room, centres)
    return x, np.array([bench.is_hit(room, p) for p in world])


def finder_sources_hash():
    """Hash of the exit finder's sources: changed candidates or features invalidate the cached
    training examples."""
    digest = hashlib.sha1()
    folder = os.path.join(SRC, "sparse_nav", "exit_finder")
    for name in sorted(os.listdir(folder)):
        if name.endswith(".py"):
            with open(os.path.join(folder, name), "rb") as handle:
                digest.update(handle.read())
    return digest.hexdigest()[:12]


def examples(seeds, cache, jobs, cfg):
    """(features, labels, rooms used) of the seeds' rooms, cached in the scan cache under the
    seeds and a hash of the finder's sources."""
    path = os.path.join(cache, f"door_examples_{seeds.start}-{seeds.stop - 1}_"
                               f"{finder_sources_hash()}.npz")
    if os.path.isfile(path):
        with np.load(path) as data:
            return data["x"], data["y"], int(data["rooms"])
    rooms = bench.load_rooms(seeds, cache, jobs)
    if jobs > 1:
        with multiprocessing.Pool(jobs) as pool:
            found = pool.starmap(room_examples, [(room, cfg) for room in rooms], chunksize=8)
    else:
        found = [room_examples(room, cfg) for room in rooms]
    found = [f for f in found if f is not None]
    xs, ys = [f[0] for f in found], [f[1] for f in found]
    x, y = np.vstack(xs), np.concatenate(ys)
    tmp = path + ".tmp.npz"
    np.savez_compressed(tmp, x=x, y=y, rooms=len(xs))
    os.replace(tmp, path)
    return x, y, len(xs)


def export(model):
    """A fitted binary HistGradientBoostingClassifier as a DoorRanker (its leaf values already
    carry the learning rate)."""
    trees = []
    for (predictor,) in model._predictors:
        nodes = predictor.nodes
        leaf = nodes["is_leaf"].astype(bool)
        trees.append({"feature": np.where(leaf, -1, nodes["feature_idx"]).tolist(),
                      "threshold": np.where(leaf, 0.0, nodes["num_threshold"]).tolist(),
                      "left": np.where(leaf, -1, nodes["left"]).tolist(),
                      "right": np.where(leaf, -1, nodes["right"]).tolist(),
                      "value": np.where(leaf, nodes["value"], 0.0).tolist()})
    return DoorRanker(float(np.ravel(model._baseline_prediction)[0]), 1.0, trees)


def parse_seeds(text):
    lo, _, hi = text.partition("-")
    return range(int(lo), int(hi or lo) + 1)


def main(argv=None):
    from sklearn import __version__ as sklearn_version
    from sklearn.ensemble import HistGradientBoostingClassifier

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", default="400-5399", help="training seeds, FIRST-LAST")
    parser.add_argument("--cache", default=None, help="scan cache (bench_exit_finder's)")
    parser.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1))
    parser.add_argument("--out", default=PACKAGED_MODEL)
    args = parser.parse_args(argv)
    seeds = parse_seeds(args.seeds)
    if seeds.start < bench.DEFAULT_ROOMS:
        print(f"train_door_ranker: seeds below {bench.DEFAULT_ROOMS} are the benchmark's rooms; "
              "training on them would score the model on what it learned", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    x, y, n_rooms = examples(seeds, args.cache or bench.default_cache(), args.jobs,
                             ExitFinderConfig())
    model = HistGradientBoostingClassifier(**PARAMS).fit(x, y)
    ranker = export(model)
    mismatch = np.abs(ranker.probability(x) - model.predict_proba(x)[:, 1]).max()
    if mismatch > 1e-9:
        print(f"train_door_ranker: the exported model differs from scikit-learn's by {mismatch}",
              file=sys.stderr)
        return 1
    ranker.info = {"trained_on": f"random_world seeds {seeds.start}-{seeds.stop - 1}",
                   "rooms": n_rooms, "candidates": int(len(y)), "positives": int(y.sum()),
                   "params": PARAMS, "sklearn": sklearn_version,
                   "script": "bench/train_door_ranker.py"}
    tmp = args.out + ".tmp"
    with open(tmp, "w", encoding="utf-8") as handle:
        handle.write(json.dumps(ranker.to_dict(), separators=(",", ":")) + "\n")
    os.replace(tmp, args.out)
    print(f"{n_rooms} rooms, {len(y)} candidates ({int(y.sum())} near a true exit); "
          f"{time.perf_counter() - t0:.0f} s; wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
