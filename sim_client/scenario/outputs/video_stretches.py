"""A video's stretches: rendered by processes of their own (see :func:`~sim_client.scenario.outputs.render.render_video`)
and joined into one MP4 without re-encoding."""

from __future__ import annotations

import os
import pathlib
from collections.abc import Sequence
from typing import Any

RENDER_WALL_S = 600.0  # [s of wall time] the longest a stretch may take


class RenderProcess:
    """``function(*args)`` (a stretch's renderer, returning its frame count) in ``python -m
    sim_client.scenario.outputs.video_stretches JOB``, a process of its own: the renderer's Python and GL calls run
    beside this process's. Started with ``subprocess``, not ``multiprocessing``, which would import the caller's
    main script again. The call is pickled into ``job_path`` (the function by its module and name)."""

    def __init__(self, function: Any, args: tuple[Any, ...], job_path: pathlib.Path) -> None:
        import pickle
        import subprocess
        import sys

        self._job_path = job_path
        job_path.write_bytes(pickle.dumps((function, args)))
        self._process = subprocess.Popen([sys.executable, "-m", __name__, str(job_path)], stdout=subprocess.PIPE,
                                         stderr=subprocess.PIPE, text=True, env=dict(os.environ))

    def result(self) -> int:
        """The frames the stretch has, once written.

        Raises:
            RuntimeError: the process failed (its error output is in the message).
        """
        out, err = self._process.communicate(timeout=RENDER_WALL_S)
        if self._process.returncode != 0:
            raise RuntimeError(f"rendering a stretch of the video failed (exit {self._process.returncode}): "
                               f"{err.strip()[-1500:]}")
        return int(out.split()[-1])

    def close(self) -> None:
        if self._process.poll() is None:
            self._process.kill()
            self._process.wait()
        self._job_path.unlink(missing_ok=True)


def join(parts: Sequence[pathlib.Path], path: pathlib.Path) -> None:
    """Join MP4 stretches encoded alike into ``path`` (ffmpeg's concat demuxer, no re-encoding)."""
    import subprocess

    import imageio_ffmpeg

    listing = path.with_name(f".{path.stem}.parts.txt")
    listing.write_text("".join(f"file '{part.resolve()}'\n" for part in parts))
    try:
        done = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-loglevel", "error", "-f", "concat", "-safe", "0",
                               "-i", str(listing), "-c", "copy", "-movflags", "+faststart", str(path)],
                              capture_output=True, text=True, timeout=120)
    finally:
        listing.unlink(missing_ok=True)
    if done.returncode != 0:
        raise RuntimeError(f"joining the video's stretches failed: {done.stderr.strip()[-500:]}")


if __name__ == "__main__":  # a stretch of a video (see RenderProcess): its job file in, its frame count out
    import pickle
    import sys

    function, args = pickle.loads(pathlib.Path(sys.argv[1]).read_bytes())
    print(function(*args))
