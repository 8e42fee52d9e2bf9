"""The PNG figures of a simulation drawn in a second process that starts before the simulation does.

Importing matplotlib and drawing the four figures of `rtchannel simulate` cost about as much CPU time as a
points simulation itself (0.4 s to import, 0.5 s to draw, measured). Both are independent of the simulation
until its signatures exist, so `FigureWorker` forks one child process at once, which imports the plotting
module while the parent simulates on the other core, and draws and writes the figures when handed the
signatures (`save_figures`, the same function and files as in-process). On a machine without a spare core
the work is only moved, not added to (one fork and the pickled signatures, a few ms).

A fork copies the state of every lock but runs only the calling thread, so a lock another thread holds at
that moment stays held in the child for ever. The child is therefore forked only where that cannot happen:
on Linux, from a process whose only Python thread is the caller (the `rtchannel` command at its start; not a
test runner or a program that has simulated before, whose synthesis and progress-bar threads live on). Elsewhere,
or if the child cannot start, dies or does not answer within `TIMEOUT_S`, the figures are drawn in this
process. The child never prints: the caller reports the paths it returns.
"""
from __future__ import annotations

import multiprocessing
import os
import sys
import threading
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from pathlib import Path

TIMEOUT_S = 300.0  # the longest wait for the child's figures (drawn in ~1 s) before drawing them here


def _serve(conn) -> None:
    """The child: import the figure code, then draw what the parent sends (EOF: nothing to draw)."""
    status = 0
    try:
        import processing.plots.signatures as plots  # matplotlib, before the signatures exist

        try:
            sigs, out_dir, title = conn.recv()
        except EOFError:
            return
        try:
            conn.send(("ok", plots.save_figures(sigs, out_dir, title)))
        except Exception as e:  # noqa: BLE001 - handed to the parent, which raises it
            conn.send(("error", e))
    except BaseException:  # noqa: BLE001 - the parent draws the figures itself
        status = 1
    finally:
        conn.close()
        os._exit(status)  # no interpreter teardown: nothing of the parent's must run twice


def can_fork() -> bool:
    """Whether this process may fork the figure child now (Linux, no other Python thread)."""
    return (sys.platform.startswith("linux") and "fork" in multiprocessing.get_all_start_methods()
            and threading.active_count() == 1)


class FigureWorker:
    """A child process drawing `processing.plots.signatures.save_figures` (use as a context manager: it
    starts on entry when `can_fork`, and is stopped on exit)."""

    def __init__(self, enabled: bool = True):
        self._proc: BaseProcess | None = None
        self._conn: Connection | None = None
        if enabled and can_fork():
            ctx = multiprocessing.get_context("fork")
            try:
                self._conn, child = ctx.Pipe()
                self._proc = ctx.Process(target=_serve, args=(child,), daemon=True, name="rtchannel-figures")
                self._proc.start()
                child.close()
            except OSError:  # no process could be started (limits): draw in this process
                self.close()

    def __enter__(self) -> "FigureWorker":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def in_child(self) -> bool:
        """Whether the figures will be drawn in the child process."""
        return self._proc is not None

    def save_figures(self, sigs, out_dir: str | Path, title: str = "") -> list[Path]:
        """`processing.plots.signatures.save_figures(sigs, out_dir, title)`, in the child when it runs.

        Args:
            sigs: {link name: Signature} (or one Signature).
            out_dir: folder to write into (created if missing).
            title: figure title.

        Returns:
            The paths written (pvt.png, mean_velocity.png, range.png, range_doppler.png).
        """
        conn = self._conn
        if self._proc is not None and conn is not None:
            try:
                conn.send((sigs, Path(out_dir), title))
                answer = conn.recv() if conn.poll(TIMEOUT_S) else None
            except (OSError, EOFError):  # the child died (killed, out of memory)
                answer = None
            self.close(answered=answer is not None)
            if answer is not None:
                status, value = answer
                if status == "error":
                    raise value
                return value
        from processing.plots.signatures import save_figures

        return save_figures(sigs, Path(out_dir), title)

    def close(self, answered: bool = False) -> None:
        """Stop the child: wait for it to end once it has answered, else end it (it writes files only when
        asked to draw, each atomically, so nothing it leaves is half-written)."""
        if self._conn is not None:
            self._conn.close()
            self._conn = None
        if self._proc is not None:
            proc, self._proc = self._proc, None
            if answered:
                proc.join(5.0)  # it ends as soon as it has sent its answer
            if proc.is_alive():
                proc.kill()
            proc.join()


__all__ = ["FigureWorker", "TIMEOUT_S", "can_fork"]
