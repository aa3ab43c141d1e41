"""Long calls release the GIL: another Python thread keeps running while a batch or a build works."""

import sys
import threading
import time

import numpy as np

import cfl
import reference
from conftest import MESHES


def iterations_while_running(work):
    """How many times this thread looped while `work` ran in another thread, and how long work took."""
    started = threading.Event()
    elapsed = []

    def run():
        started.set()
        start = time.perf_counter()
        work()
        elapsed.append(time.perf_counter() - start)

    thread = threading.Thread(target=run)
    thread.start()
    started.wait()
    iterations = 0
    while thread.is_alive():
        iterations += 1
    thread.join()
    return iterations, elapsed[0]


def loop_rate():
    """Iterations per second of the loop in iterations_while_running, with nothing else running."""
    deadline = time.perf_counter() + 0.05
    iterations = 0
    while time.perf_counter() < deadline:
        iterations += 1
    return iterations / 0.05


def measure(work):
    """(iterations, allowance, seconds): this thread's loop count while `work` ran in another thread, the
    count a call holding the GIL could still leave it, and how long the call took. Such a call lets this
    thread run until it takes the GIL, up to one switch interval (5 ms) after starting, and once more when
    it returns: the allowance is four intervals' worth of iterations."""
    allowance = 4 * sys.getswitchinterval() * loop_rate()
    iterations, seconds = iterations_while_running(work)
    return iterations, allowance, seconds


# A loaded machine can stall either thread for longer than a switch interval, which makes one measurement
# say either thing: each check takes the best of three tries, which a call that holds the GIL (or one that
# releases it) still fails every time.
TRIES = 3


def assert_gil_released(work):
    tries = []
    for _ in range(TRIES):
        iterations, allowance, seconds = measure(work)
        assert seconds > 20 * sys.getswitchinterval(), "the call should be long enough to tell"
        if iterations > allowance:
            return
        tries.append((iterations, allowance, seconds))
    assert False, tries


def test_a_batch_lets_other_threads_run(models):
    rng = np.random.default_rng(13)
    poses = np.tile(np.stack([reference.random_pose(rng, 2.0) for _ in range(50)]), (800, 1, 1))
    assert_gil_released(lambda: cfl.distances(models["torus"], None, models["soup"], poses, threads=1))


def test_a_build_lets_other_threads_run():
    assert_gil_released(lambda: cfl.Model(*MESHES["torus"], resolution=64, threads=1))


def test_the_check_catches_a_call_that_holds_the_gil():
    # sum() over a range runs in C without releasing the GIL.
    tries = []
    for _ in range(TRIES):
        iterations, allowance, seconds = measure(lambda: sum(range(4 * 10**7)))
        assert seconds > 20 * sys.getswitchinterval()
        if iterations <= allowance:
            return
        tries.append((iterations, allowance, seconds))
    assert False, tries
