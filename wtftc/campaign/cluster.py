"""Dask for the campaigns (`wtftc sweep`, `wtftc compare`): a local cluster or an existing
scheduler, and what the runs in OpenFAST are doing meanwhile.

An OpenFAST run is a process of its own that may take minutes; its progress is read from
OpenFAST's own screen output in its case folder (``openfast.log``: "Time: 35 of 120
seconds." every 5 simulated seconds), by a thread of the process that waits for the
results (:class:`Watcher`). Nothing is sent back from the workers for it: on a cluster
whose workers write elsewhere, the progress of runs in flight is simply not shown.
"""

from __future__ import annotations

import os
import re
import socket
import stat
import threading
from pathlib import Path

from wtftc.errors import ConfigError

#: OpenFAST's screen output in a case folder (wtftc.openfast.engine.simulate writes it)
OPENFAST_LOG = "openfast.log"
#: OpenFAST's progress line, every 5 simulated seconds
_TIME = re.compile(rb"Time: *([0-9.eE+-]+) of *([0-9.eE+-]+) seconds")
#: the end of the log read for it [bytes]: the last lines
_TAIL = 1024


def client(scheduler: str | None, workers: int):
    """(Dask client, the local cluster it owns or None): the cluster of ``scheduler``, or a
    local one of ``workers`` processes with one thread each."""
    import logging

    from dask.distributed import Client, LocalCluster

    if scheduler:
        _refused(scheduler)
        try:
            return Client(scheduler, timeout="10s"), None
        except (OSError, TimeoutError, ValueError) as exc:
            raise ConfigError("--scheduler", scheduler, "the address of a running Dask "
                              f"scheduler, tcp://HOST:PORT ({type(exc).__name__}: {exc})"
                              ) from None
        except Exception as exc:  # noqa: BLE001 (something answered that is not Dask:
            # its reply read as a frame length of exabytes, MemoryError)
            raise ConfigError("--scheduler", scheduler, "the address of a running Dask "
                              "scheduler, tcp://HOST:PORT (something answered there, not a "
                              f"Dask scheduler: {type(exc).__name__})") from None
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                           dashboard_address=":0", silence_logs=logging.ERROR)
    return Client(cluster), cluster


#: how long the address of a tcp:// scheduler is given to answer before Dask is asked [s]
PROBE_S = 5.0


def _refused(scheduler: str) -> None:
    """A ConfigError at once where a tcp:// scheduler's address cannot be a scheduler: a
    port outside 1-65535, nothing listening there (the connection refused), or no answer
    within PROBE_S; Dask's own attempt (10 s) says what else is wrong."""
    m = re.fullmatch(r"tcp://\[?([^\]/]+?)\]?:(\d+)/?", scheduler)
    if m is None:
        return
    why = None
    port = int(m.group(2))
    if not 1 <= port <= 65535:
        why = f"port {port} is outside 1-65535"
    else:
        try:
            with socket.create_connection((m.group(1), port), timeout=PROBE_S):
                return
        except ConnectionRefusedError:
            why = "nothing listens there: the connection was refused"
        except TimeoutError:
            why = f"no answer from there within {PROBE_S:g} s"
        except (OSError, ValueError):
            return
    raise ConfigError("--scheduler", scheduler, "the address of a running Dask scheduler, "
                      f"tcp://HOST:PORT ({why})")


def close(cl, cluster) -> None:
    if cl is not None:
        cl.close()
    if cluster is not None:
        cluster.close()


def simulated(case_dir: Path, since: float) -> tuple[float, float] | None:
    """(simulated, total) seconds of the OpenFAST run in ``case_dir``, from the last progress
    line of its screen output written since the wall-clock time ``since``; None when
    there is none (not started, an attempt of an earlier call, not OpenFAST). The log is
    read as a regular file only, never through a link."""
    try:
        fd = os.open(Path(case_dir) / OPENFAST_LOG, os.O_RDONLY | os.O_NOFOLLOW
                     | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode) or st.st_mtime < since:
            return None
        tail = os.pread(fd, _TAIL, max(0, st.st_size - _TAIL))
    finally:
        os.close(fd)
    hits = _TIME.findall(tail)
    if not hits:
        return None
    try:
        t, total = float(hits[-1][0]), float(hits[-1][1])
    except ValueError:
        return None
    return (t, total) if total > 0 else None


def in_flight(folders, since: float) -> list[tuple[float, float]]:
    """:func:`simulated` of each case folder in ``folders`` that has a run in progress."""
    out = []
    for d in folders:
        s = simulated(d, since)
        if s is not None and s[0] < s[1]:
            out.append(s)
    return out


def describe(running: list[tuple[float, float]]) -> str:
    """The runs in flight in a few words: each one's simulated seconds (up to 4), else
    their mean share."""
    if not running:
        return ""
    if len(running) <= 4:
        return (f"{len(running)} in OpenFAST at "
                + ", ".join(f"{t:g}/{total:g} s" for t, total in running))
    share = sum(t / total for t, total in running) / len(running)
    return f"{len(running)} in OpenFAST, {100 * share:.0f} % simulated on average"


class Watcher(threading.Thread):
    """Calls ``tick()`` every ``every`` seconds until :meth:`stop` (a daemon thread: it
    never keeps the process alive)."""

    def __init__(self, tick, every: float):
        super().__init__(daemon=True, name="wtftc-progress")
        self._tick, self._every = tick, every
        self._stop_event = threading.Event()

    def run(self) -> None:
        while not self._stop_event.wait(self._every):
            try:
                self._tick()
            except Exception:  # noqa: BLE001 - progress must never stop a campaign
                pass

    def stop(self) -> None:
        self._stop_event.set()
