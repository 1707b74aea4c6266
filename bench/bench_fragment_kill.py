#!/usr/bin/python3
"""Fragment writes under SIGKILL: the cartographer's atomic store against a naive in-place write.

A forked child saves one fragment over and over; the parent kills it with SIGKILL at a random
moment (seeded) within its next saves, then loads the fragment. A load is "broken" when it is
refused (truncated, checksum) or missing; "old or new" otherwise. The naive writer (open the
target, write, close) is the control: it shows that the kills do land inside writes. No data from
../shared is used. Writes bench/results/fragment_kill.json.

    /usr/bin/python3 bench/bench_fragment_kill.py [--kills 200] [--seed 7]
"""
import argparse
import json
import os
import signal
import statistics
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "src"))

from sparse_nav.cartographer.store import FragmentError, FragmentStore, encode  # noqa: E402


def points_of(generation):
    rng = np.random.default_rng(generation)
    return rng.uniform(-10.0, 10.0, size=(20000 + 3000 * (generation % 7), 3))


def naive_save(store, name, points, meta):
    with open(store.path(name), "wb") as f:
        f.write(encode(points, meta))


def atomic_save(store, name, points, meta):
    store.save(name, points, meta)


def run(save, kills, seed, directory):
    store = FragmentStore(directory)
    save(store, "frag", points_of(0), {"generation": 0})
    durations = []
    for g in range(3):
        start = time.monotonic()
        save(store, "probe", points_of(g), {"generation": g})
        durations.append(time.monotonic() - start)
    os.unlink(store.path("probe"))
    save_s = statistics.median(durations)
    rng = np.random.default_rng(seed)
    generation, broken, kept_old, got_new = 0, 0, 0, 0
    for _ in range(kills):
        pipe_r, pipe_w = os.pipe()
        pid = os.fork()
        if pid == 0:
            os.close(pipe_r)
            try:
                g = generation + 1
                while True:
                    save(store, "frag", points_of(g), {"generation": g})
                    os.write(pipe_w, b"s")
                    g += 1
            finally:
                os._exit(1)
        os.close(pipe_w)
        for _ in range(int(rng.integers(0, 2))):
            os.read(pipe_r, 1)
        time.sleep(rng.uniform(0.0, 1.5 * save_s))
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        os.close(pipe_r)
        store.remove_stale_temporaries()
        try:
            points, meta = store.load("frag")
            ok = np.array_equal(points, points_of(meta["generation"]).astype(np.float32))
        except FragmentError:
            ok = False
        if not ok:
            broken += 1
            # Start the next round from a good file, as a restart that re-creates it would.
            save(store, "frag", points_of(generation), {"generation": generation})
            continue
        if meta["generation"] > generation:
            got_new += 1
        else:
            kept_old += 1
        generation = meta["generation"]
    return {"kills": kills, "broken_loads": broken, "old_fragment": kept_old,
            "new_fragment": got_new, "median_save_ms": round(1000 * save_s, 2)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kills", type=int, default=200)
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args()
    results = {}
    for label, save in (("atomic (FragmentStore)", atomic_save), ("naive in-place", naive_save)):
        with tempfile.TemporaryDirectory() as directory:
            results[label] = run(save, args.kills, args.seed, directory)
    print(f"{'writer':24s} {'kills':>6s} {'broken':>7s} {'old':>5s} {'new':>5s} {'save ms':>8s}")
    for label, r in results.items():
        print(f"{label:24s} {r['kills']:6d} {r['broken_loads']:7d} {r['old_fragment']:5d} "
              f"{r['new_fragment']:5d} {r['median_save_ms']:8.2f}")
    os.makedirs(os.path.join(HERE, "results"), exist_ok=True)
    with open(os.path.join(HERE, "results", "fragment_kill.json"), "w") as f:
        json.dump({"seed": args.seed, "results": results}, f, indent=1)
    return 1 if results["atomic (FragmentStore)"]["broken_loads"] else 0


if __name__ == "__main__":
    sys.exit(main())
