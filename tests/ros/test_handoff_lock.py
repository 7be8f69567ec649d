"""The /sim lock's hand-off: a holder that takes it straight back still lets a waiting thread in, and only then waits."""

from __future__ import annotations

import threading

import mujoco

from nodes.sim.handoff import HandOffLock

DEADLINE_S = 30.0  # a bound on a loaded machine, not a speed
BOX = "<mujoco><worldbody><geom type='plane' size='1 1 0.1'/><body pos='0 0 1'><freejoint/>" \
      "<geom type='box' size='0.1 0.1 0.1'/></body></worldbody></mujoco>"


def test_a_thread_waiting_for_the_lock_gets_it_between_two_stretches_of_a_busy_holder():
    lock = HandOffLock()
    stop = threading.Event()
    stretches: list[str] = []  # who held the lock, in order
    handed: list[bool] = []
    model = mujoco.MjModel.from_xml_string(BOX)
    data = mujoco.MjData(model)

    def busy_holder() -> None:  # the physics thread as fast as possible: take, step (the GIL is let go), hand off
        while not stop.is_set():
            lock.acquire()
            stretches.append("holder")
            mujoco.mj_step(model, data, nstep=200)
            handed.append(lock.hand_off(DEADLINE_S))

    holder = threading.Thread(target=busy_holder)
    holder.start()
    try:
        for _ in range(20):
            taken = lock.acquire(timeout=DEADLINE_S)
            assert taken, "the waiter never got the lock from the busy holder"
            with lock:  # reentrant
                stretches.append("waiter")
            lock.release()
    finally:
        stop.set()
        holder.join(DEADLINE_S)
    assert not holder.is_alive()
    assert stretches.count("waiter") == 20
    assert any(handed), "the holder handed the lock over to a waiting thread"
    # A hand-off waited for the waiter: the holder's next stretch came after one of the waiter's.
    holder_at = [i for i, who in enumerate(stretches) if who == "holder"]
    for k, was_handed in enumerate(handed[:len(holder_at) - 1]):
        if was_handed:
            assert "waiter" in stretches[holder_at[k] + 1:holder_at[k + 1]], f"hand-off {k} did not wait for the waiter"


def test_with_nobody_waiting_the_hand_off_only_releases():
    lock = HandOffLock()
    lock.acquire()
    assert lock.waiting == 0
    assert lock.hand_off(DEADLINE_S) is False
    # Released: another thread takes it without blocking.
    got: list[bool] = []
    thread = threading.Thread(target=lambda: got.append(lock.acquire(blocking=False)))
    thread.start()
    thread.join(DEADLINE_S)
    assert got == [True]


def test_a_try_that_fails_is_not_counted_as_waiting():
    lock = HandOffLock()
    held, done = threading.Event(), threading.Event()

    def hold() -> None:
        with lock:
            held.set()
            done.wait(DEADLINE_S)

    thread = threading.Thread(target=hold)
    thread.start()
    assert held.wait(DEADLINE_S)
    assert lock.acquire(blocking=False) is False
    assert lock.acquire(timeout=0.01) is False  # timed out: counted while it waited, not after
    assert lock.waiting == 0
    done.set()
    thread.join(DEADLINE_S)
    assert lock.acquire(blocking=False)
    lock.release()
