"""The simulation's lock: reentrant, and its busy holder hands it over only to a thread that waits for it.

The physics thread takes the lock for every stretch of stepping and, run as fast as possible, takes it
straight back: a plain lock is not fair, so a service waiting for it could wait for ever. Yielding the
processor after every stretch (``time.sleep(0)``) lets the waiter in, but on a loaded machine a yield
also gives the core away, and it is paid whether anyone waits or not. :class:`HandOffLock` counts the
threads blocked in :meth:`~HandOffLock.acquire`; :meth:`~HandOffLock.hand_off` releases the lock and,
only when one of them waits, waits until one has taken it.
"""

from __future__ import annotations

import threading
from types import TracebackType


class HandOffLock:
    """A reentrant lock (a ``threading.RLock`` inside) with :meth:`hand_off` for a holder that takes it back at once."""

    def __init__(self) -> None:
        self._lock = threading.RLock()
        self._waiting = 0  # threads blocked in acquire
        self._count_lock = threading.Lock()  # guards _waiting (+= is not atomic across threads)
        self._taken = threading.Event()  # set when a thread that waited got the lock

    @property
    def waiting(self) -> int:
        """How many threads are blocked waiting for the lock."""
        return self._waiting

    def acquire(self, blocking: bool = True, timeout: float = -1) -> bool:
        """Take the lock (see ``threading.RLock.acquire``); a thread that has to wait is counted meanwhile."""
        if self._lock.acquire(False):
            return True
        if not blocking:
            return False
        with self._count_lock:
            self._waiting += 1
        try:
            taken = self._lock.acquire(True, timeout)
        finally:
            with self._count_lock:
                self._waiting -= 1
        if taken:
            self._taken.set()
        return taken

    def release(self) -> None:
        """Release the lock once (see ``threading.RLock.release``)."""
        self._lock.release()

    def __enter__(self) -> bool:
        return self.acquire()

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.release()

    def hand_off(self, timeout_s: float) -> bool:
        """Release the lock (held once by this thread); if a thread waits for it, wait until one has taken it.

        Returns whether it was handed over (False at once when nobody waits, or after ``timeout_s`` [s]
        if the waiter did not take it by then, e.g. its own acquire timed out).
        """
        waited = self._waiting > 0
        if waited:
            self._taken.clear()  # under the lock: no waiter can have taken it yet
        self.release()
        return waited and self._taken.wait(timeout_s)
