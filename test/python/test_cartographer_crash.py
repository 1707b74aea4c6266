"""Fault test: a writer killed with SIGKILL at random moments never leaves a broken fragment.

200 seeded kills of a forked child process that saves the same fragment in a loop (the code the
cartographer node saves with); after each kill the fragment loads, holds exactly the points of
one complete generation, and never an older generation than the one loaded before: old or new,
never a mixture. The child reports each finished save on a pipe; the parent kills it at a random
moment within the following saves.
"""
import os
import signal
import statistics
import time

import numpy as np

from generation import generation_points
from sparse_nav.cartographer.store import FragmentStore

KILLS = 200


def _writer(store, first_generation, pipe_w):
    """The child: save generation after generation, one byte on the pipe after each."""
    generation = first_generation
    while True:
        store.save("frag", generation_points(generation), {"generation": generation})
        os.write(pipe_w, b"s")
        generation += 1


def _save_duration(store):
    durations = []
    for g in range(3):
        start = time.monotonic()
        store.save("probe", generation_points(g), {"generation": g})
        durations.append(time.monotonic() - start)
    store.delete("probe")
    return statistics.median(durations)


def test_sigkill_while_saving_leaves_old_or_new(tmp_path):
    store = FragmentStore(str(tmp_path))
    store.save("frag", generation_points(0), {"generation": 0})
    save_s = _save_duration(store)
    rng = np.random.default_rng(7)
    previous = 0
    interrupted_writes = 0
    advanced = 0
    for _ in range(KILLS):
        pipe_r, pipe_w = os.pipe()
        pid = os.fork()
        if pid == 0:
            os.close(pipe_r)
            try:
                _writer(store, previous + 1, pipe_w)
            finally:
                os._exit(1)
        os.close(pipe_w)
        for _ in range(int(rng.integers(0, 2))):
            os.read(pipe_r, 1)
        time.sleep(rng.uniform(0.0, 1.5 * save_s))
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        os.close(pipe_r)
        interrupted_writes += store.remove_stale_temporaries()
        points, meta = store.load("frag")
        generation = meta["generation"]
        assert generation >= previous
        np.testing.assert_array_equal(points, generation_points(generation).astype(np.float32))
        advanced += generation > previous
        previous = generation
        assert store.names() == ["frag"]
    print(f"\n{KILLS} kills: {interrupted_writes} interrupted a write (temporary file left), "
          f"{advanced} came after a new generation was renamed in, last generation {previous}, "
          "0 broken loads")
    # The kills must have hit writes in progress, or this test would prove nothing.
    assert interrupted_writes > 0
    assert advanced > 0
