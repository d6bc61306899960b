"""A scene's branch of periodic orbits on a Dask cluster (``nsfem periodic --continue ... --workers N |
--scheduler ADDRESS``): the pieces of :func:`.scene_branch.branch_of_scene` that do not depend on each other run
as tasks.

Independent are the two sides of a start inside [LOW, HIGH] (each continued from the start's orbit towards one
end) and the period-doubled branches switched onto (each from its located period doubling). The start's orbit is
found once, in the calling process, and sent; each task rebuilds its systems on its worker from the branch's
:class:`~.scene_branch._Family` (the scene, the start's model and reduction, the loader of other keys' scenes),
scattered to the workers once. A side's task follows its branch without switching (:func:`side_task`); the
client then submits a task per period doubling on it (:func:`doubled_task`: :func:`.branch.doubled_start` and
the doubled branch, as :func:`.branch.orbit_branch` switches onto it). Each point's record is made on the worker
exactly as the serial path makes it (:func:`.scene_branch.point_record`) and streamed back through a
``distributed.Queue`` as it is found, so progress lines and the branch so far (``on_point``, an interrupt) come
as they do in one process; the records a finished task returns are the ones kept. The sides are merged in their
order, each with its doubled branches in the order of its bifurcations: the serial path's result. Ctrl-C on the
client cancels the tasks; running ones end at their next point (a ``distributed.Event`` they look at).

The cluster is the one ``nsfem sweep`` uses (:func:`nsfem.sweep._client`: a given client, one connected to a
scheduler, or a LocalCluster of worker processes with one BLAS thread each), with its limits and its closing.
"""

from __future__ import annotations

import contextlib
import pickle
import uuid
from typing import Callable

import numpy as np

from ..errors import NsfemError

#: seconds between looks at the points' queue while the tasks run (a point is shown at most this late). Not a
#: blocking get on the queue: its timeout is logged by the scheduler as an error with a traceback
POLL_S = 0.5


def check_cluster_options(client, workers, scheduler) -> bool:
    """Refuse bad cluster options (one line naming the option) before any computation; True when the branch runs
    on a cluster (a client, a scheduler, or ``workers`` >= 2), False for the serial path (none, or 1 worker)."""
    from ..sweep import check_workers

    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, (int, np.integer))):
        raise NsfemError(f"--workers must be a positive integer, got {workers!r}")
    if workers is not None and (scheduler or client is not None):
        raise NsfemError("--workers cannot be combined with --scheduler (the cluster has its own workers)")
    if scheduler is not None and client is not None:
        raise NsfemError("branch_of_scene: give a client or a scheduler address, not both")
    if scheduler is not None and (not isinstance(scheduler, str) or not scheduler.strip()):
        raise NsfemError(f"--scheduler must be an address such as tcp://127.0.0.1:8786, got {scheduler!r}")
    check_workers(workers)
    if client is not None:
        from distributed import Client

        if not isinstance(client, Client):
            raise NsfemError(f"branch_of_scene: client must be a distributed.Client, got {type(client).__name__}")
    return client is not None or bool(scheduler) or (workers is not None and workers > 1)


def connect(client, workers: int | None, scheduler: str | None, sides: int) -> tuple:
    """(client, things to close, the workers' warm-up tasks): as ``nsfem sweep`` connects (a LocalCluster of at most one worker per side, at
    least one). Each worker starts importing the continuation's modules at once (2.7 s measured on a loaded
    machine), while this process finds the start's orbit."""
    from ..sweep import _client

    cl, closing = _client(client, workers, scheduler, max(1, sides))
    warming = []   # (kept: a future released before it runs is forgotten by the scheduler)
    with contextlib.suppress(Exception):   # (a speed-up only)
        for address in cl.nthreads():
            warming.append(cl.submit(_import_modules, workers=[address], allow_other_workers=False, pure=False,
                                     key=f"nsfem-branch-import-{uuid.uuid4().hex}"))
    return cl, closing, warming


def _import_modules() -> None:
    """On a worker: import what its tasks will need."""
    from . import branch, scene_branch  # noqa: F401


def close(cluster: tuple) -> None:
    """Close what :func:`connect` opened (a given client stays open), a second Ctrl-C held off meanwhile."""
    from ..sweep import _close, _hold_signals, _release_signals

    held = _hold_signals()
    try:
        _close(cluster[1])
    finally:
        _release_signals(held)


class BranchCancelled(Exception):
    """Raised in a task whose branch was interrupted on the client (a running task cannot be stopped otherwise:
    it would go on to its end on a cluster the client does not close)."""


def _stream(queue_name: str, tag: int) -> Callable[[int, dict], None]:
    """On a worker: put(multiple, record) puts (tag, sequence number, multiple, the record pickled) on the client's
    queue (best effort: a queue gone only loses progress lines, the task's result keeps every record), after
    raising :class:`BranchCancelled` if the client has set the branch's stop event."""
    from distributed import Event, Queue

    queue, stop = Queue(queue_name), Event(f"{queue_name}-stop")
    seq = [0]

    def put(mult: int, rec: dict) -> None:
        cancelled = False
        with contextlib.suppress(Exception):
            cancelled = stop.is_set()
        if cancelled:
            raise BranchCancelled("the branch was interrupted")
        with contextlib.suppress(Exception):
            queue.put([tag, seq[0], int(mult), pickle.dumps(rec)])
        seq[0] += 1

    return put


def side_task(family, q0, v0, p0: float, end: float, key: str, multiple: int, t0: float, tol: float,
              step: float | None, steps: int, queue_name: str, tag: int):
    """On a worker: one side of the branch, from the start's orbit (q0, v0 at p0, section t0) towards ``end``,
    without switching onto doubled branches. Returns (the :class:`~.branch.OrbitBranch`, its points' records in
    the order found)."""
    from .branch import orbit_branch
    from .scene_branch import point_record

    put, recs = _stream(queue_name, tag), []

    def on_point(bp, mult: int) -> None:
        rec = point_record(family, bp, mult, key, t0)
        recs.append(rec)
        put(mult, rec)

    br = orbit_branch(family.system_at, family.period_at, q0, v0, p0, end, key=key, multiple=multiple, t0=t0,
                      tol=tol, step=step, max_steps=steps, switch=False, on_point=on_point)
    return br, recs


def doubled_task(family, bif: dict, p_end: float, key: str, multiple: int, t0_side: float, t0: float, tol: float,
                 step: float | None, steps: int, queue_name: str, tag: int):
    """On a worker: the period-doubled branch switched onto at ``bif`` (a period doubling of a side's branch of
    period ``multiple``, section ``t0_side``), as :func:`.branch.orbit_branch` switches (one level). Returns (its
    JSON dict as the serial path reports it, or the reason the switch failed (a str); its points' records in the
    order found); ``t0``: the first orbit's section, at which the records are made."""
    from .branch import doubled_start, orbit_branch
    from .scene_branch import _doubled, point_record, record_key

    put, recs, records = _stream(queue_name, tag), [], {}

    def on_point(bp, mult: int) -> None:
        rec = point_record(family, bp, mult, key, t0)
        records[record_key(mult, bp.p, bp.u)] = rec
        recs.append(rec)
        put(mult, rec)

    try:
        q, v, p, t_d = doubled_start(family.system_at, family.period_at, bif, p_end, multiple=multiple, t0=t0_side,
                                     tol=tol)
        d = orbit_branch(family.system_at, family.period_at, q, v, p, p_end, key=key, multiple=2 * multiple, t0=t_d,
                         tol=tol, step=step, max_steps=steps, switch=True, depth=0, on_point=on_point)
    except NsfemError as exc:
        return str(exc), recs
    return _doubled(d, family, d.t0, records if d.t0 == t0 else {}), recs


def _result(fut, end: float):
    """A finished task's result; its error raised as the serial path raises it, a cluster's failure (a worker
    lost, the scheduler gone) as one line."""
    try:
        return fut.result()
    except (NsfemError, KeyboardInterrupt):
        raise
    except Exception as exc:
        from asyncio import CancelledError

        if isinstance(exc, (CancelledError, OSError)) or type(exc).__module__.split(".")[0] == "distributed":
            why = " ".join(f"{type(exc).__name__}: {exc}".split())[:200]
            raise NsfemError(f"the Dask cluster failed on the branch towards {end:g} ({why}); run again, or "
                             "without --workers/--scheduler") from None
        raise


def follow_sides(client, family, so, sides: list[float], p0: float, *, key: str, multiple: int, tol: float,
                 step: float | None, steps: int, accept: Callable[[dict, int, int], None],
                 merge: Callable[[int, str, str, list, list], None]) -> None:
    """Follow the branch's ``sides`` from the start ``so`` (a :class:`~.scene.SceneOrbit`) on ``client``'s
    cluster. ``accept(record, multiple, side)`` is called with each point as it comes (each task's points in their
    order, the tasks' interleaved), ``merge(side, stop, reason, bifurcations, doubled)`` once a side and its
    doubled branches are done, the sides in their order. Ctrl-C cancels the tasks and raises KeyboardInterrupt
    (what was accepted and merged stays)."""
    from distributed import Event, Queue, wait

    queue_name = f"nsfem-branch-{uuid.uuid4().hex}"
    queue, stop = Queue(queue_name, client=client), Event(f"{queue_name}-stop", client=client)
    # the family without its cached systems, sent once to every worker
    [shared] = client.scatter([family.fresh()], broadcast=True, hash=False)
    t0 = float(so.orbit.t0)
    tasks: dict = {}            # future -> (tag, side, kind, bifurcation or None)
    seen: dict[int, int] = {}   # tag -> records accepted
    side_of: dict[int, int] = {}
    done_side: dict[int, tuple] = {}          # side -> (OrbitBranch, {bifurcation index: result})
    waiting: dict[int, int] = {}              # side -> doubled tasks still running
    merged = [0]

    def submit(fn, side: int, kind: str, index, *args) -> None:
        tag = len(side_of)
        side_of[tag], seen[tag] = side, 0
        fut = client.submit(fn, shared, *args, queue_name, tag, key=f"nsfem-branch-{kind}-{uuid.uuid4().hex}",
                            pure=False)
        tasks[fut] = (tag, side, kind, index)

    def take(tag: int, seq: int, mult: int, rec: dict) -> None:
        if seq == seen[tag]:   # each task's records once, in order
            seen[tag] += 1
            accept(rec, mult, side_of[tag])

    def drain() -> None:
        """The points on the queue now."""
        items = []
        with contextlib.suppress(Exception):   # (a queue gone: the tasks' results keep every point)
            items = queue.get(batch=True)
        for tag, seq, mult, blob in items:
            take(tag, seq, mult, pickle.loads(blob))

    def merge_ready() -> None:
        while merged[0] < len(sides) and merged[0] in done_side and not waiting.get(merged[0]):
            k = merged[0]
            br, doubled = done_side[k]
            bifs = [dict(b) for b in br.bifurcations]
            out = []
            for i, b in enumerate(bifs):
                if i in doubled:
                    if isinstance(doubled[i], str):
                        b["switch_failed"] = doubled[i]
                    else:
                        out.append(doubled[i])
            merge(k, br.stop, br.reason, bifs, out)
            merged[0] += 1

    for k, end in enumerate(sides):
        submit(side_task, k, "side", None, so.orbit.q0, so.orbit.v0, p0, end, key, multiple, t0, tol, step, steps)
    stopped = False   # (by Ctrl-C or an error: tasks may still run)
    try:
        while tasks:
            with contextlib.suppress(TimeoutError):   # (none finished within POLL_S)
                wait(list(tasks), timeout=POLL_S, return_when="FIRST_COMPLETED")
            drain()
            for fut in [f for f in tasks if f.done()]:
                tag, k, kind, index = tasks.pop(fut)
                value, recs = _result(fut, sides[k])
                for seq, rec in enumerate(recs):
                    take(tag, seq, rec.get("multiple", multiple), rec)
                if kind == "side":
                    done_side[k] = (value, {})
                    for i, b in enumerate(value.bifurcations):
                        if b["kind"] == "period-doubling":
                            waiting[k] = waiting.get(k, 0) + 1
                            submit(doubled_task, k, "doubled", i, b, sides[k], key, multiple, value.t0, t0, tol,
                                   step, steps)
                else:
                    done_side[k][1][index] = value
                    waiting[k] -= 1
            merge_ready()
    except BaseException:
        stopped = True
        with contextlib.suppress(Exception):   # the running tasks end at their next point, the others at once
            stop.set()
            client.cancel(list(tasks))
        raise
    finally:   # what the branch left on the scheduler (the stop event stays set for tasks still running)
        with contextlib.suppress(Exception):
            shared.release()
            queue.close()
            if not stopped:
                stop.clear()
