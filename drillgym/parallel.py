"""One way to run drillgym's parallel loops: on local processes or on a Ray cluster.

Both backends are ``concurrent.futures.Executor`` objects, so every loop that already took an
``executor`` (the evaluation harness, :func:`drillgym.bifurcation.sweep_constant`,
:func:`drillgym.bifurcation.compute_diagram`) runs unchanged on either:

* :class:`LocalExecutor` - a process pool on this machine (the default of every command);
* :class:`RayExecutor` - Ray core tasks on a cluster (``--ray auto``), on a Ray instance started
  on this machine (``--ray local``) or at an address (``--ray HOST:PORT``, ``--ray ray://HOST:10001``).

What both guarantee:

* **failures are never silently dropped**: a task whose worker died (killed, out of memory, a node
  lost) is retried ``retries`` times; an exception raised by the task itself is deterministic (same
  inputs, same seeds) and is not retried but re-raised as :class:`TaskFailed`, whose one-line
  message names the function, its inputs and the error;
* **the same inputs give the same results** on either backend: tasks carry all their inputs and
  seeds, nothing depends on which process runs them.

Work should be shipped in chunks (one batched core call per task, e.g. ten plants x all targets),
so that scheduling overhead (a few ms per Ray task) stays small; :func:`parallelism` tells a loop
how many workers there are to split for. Compiled kernels are not recompiled per task: drillgym caches
them on disk by content (``$DRILLGYM_KERNEL_CACHE``, default ``~/.cache/drillgym/kernels``) and every
worker process loads them; Ray workers are reused across tasks and get ``DRILLGYM_KERNEL_CACHE``
(and ``DRILLGYM_SIMD``) from the driver when it sets them.

    >>> with open_executor("local", workers=2) as ex:          # Ray on this machine; None: process pool
    ...     results = map_ordered(ex, f, [(chunk,) for chunk in chunks], progress=bar.update)
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from typing import Any

import numpy as np

from .errors import InputError, UnavailableError

__all__ = [
    "TaskFailed",
    "RayUnavailable",
    "LocalExecutor",
    "RayExecutor",
    "open_executor",
    "connect_ray",
    "map_ordered",
    "parallelism",
    "describe_inputs",
    "RAY_HELP",
]

RAY_HELP = (
    "run on Ray: 'auto' (a running cluster, started with `ray start --head`), 'local' (start one "
    "on this machine) or the address of a cluster's head (HOST:PORT or ray://HOST:10001)"
)
_ENV_FORWARDED = ("DRILLGYM_KERNEL_CACHE", "DRILLGYM_SIMD")


class TaskFailed(RuntimeError):
    """A task failed (after its retries); the message names the function, its inputs and the error."""

    def __init__(self, fn: Callable, args: tuple, kwargs: dict, error: BaseException | str, attempts: int = 1):
        self.fn_name = getattr(fn, "__qualname__", repr(fn))
        self.inputs = (args, kwargs)
        self.error = error
        self.attempts = attempts
        what = error if isinstance(error, str) else f"{type(error).__name__}: {_first_line(error)}"
        tries = f" after {attempts} attempts" if attempts > 1 else ""
        super().__init__(f"task {self.fn_name}({describe_inputs(args, kwargs)}) failed{tries}: {what}")

    def __reduce__(self):  # picklable across processes (the inputs as their description)
        return (_rebuild_failed, (self.args[0],))


def _rebuild_failed(message: str) -> RuntimeError:
    return RuntimeError(message)


class RayUnavailable(UnavailableError):
    """Ray is not installed or the cluster named by ``--ray`` cannot be reached."""


def _settle(fut: Future, *, result: Any = None, error: BaseException | None = None) -> None:
    """Complete ``fut`` unless it was cancelled meanwhile."""
    try:
        if error is not None:
            fut.set_exception(error)
        else:
            fut.set_result(result)
    except Exception:  # InvalidStateError: cancelled by the caller in the meantime
        pass


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    lines = [ln for ln in text.splitlines() if ln.strip()]
    return lines[-1].strip() if lines else type(exc).__name__


def _short(value: Any, limit: int = 60) -> str:
    if isinstance(value, np.ndarray):
        text = (
            np.array2string(value.ravel()[:4], precision=4, separator=",")[:-1] + (",...]" if value.size > 4 else "]")
            if value.size
            else "[]"
        )
        return f"array{tuple(value.shape)} {text}"
    if isinstance(value, (list, tuple)) and len(value) > 6:
        inner = ", ".join(_short(v, 12) for v in value[:4])
        return f"{type(value).__name__}[{len(value)}]({inner}, ...)"
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def describe_inputs(args: tuple, kwargs: dict, limit: int = 400) -> str:
    """A one-line description of a task's inputs (long values shortened)."""
    parts = [_short(a) for a in args] + [f"{k}={_short(v)}" for k, v in kwargs.items()]
    text = ", ".join(parts)
    return text if len(text) <= limit else text[: limit - 3] + "..."


# --------------------------------------------------------------------------------------------- local


class LocalExecutor(Executor):
    """A process pool of ``workers`` processes on this machine; a pool broken by a dying worker is
    replaced and its tasks are resubmitted (``retries`` times each); a task's own exception becomes
    :class:`TaskFailed`."""

    def __init__(self, workers: int | None = None, *, retries: int = 2):
        if workers is not None and workers < 1:
            raise InputError(f"workers must be >= 1, got {workers}")
        self.workers = int(workers or os.cpu_count() or 1)
        self.retries = int(retries)
        self._lock = threading.Lock()
        self._pool = ProcessPoolExecutor(max_workers=self.workers)
        self._closed = False

    def submit(self, fn: Callable, /, *args: Any, **kwargs: Any) -> Future:
        if self._closed:
            raise RuntimeError("cannot submit to a LocalExecutor after shutdown")
        outer: Future = Future()
        self._launch(outer, fn, args, kwargs, attempt=1)
        return outer

    def _launch(self, outer: Future, fn: Callable, args: tuple, kwargs: dict, attempt: int) -> None:
        with self._lock:
            pool = self._pool
        try:
            inner = pool.submit(fn, *args, **kwargs)
        except (BrokenProcessPool, RuntimeError):  # broken, or shut down by a concurrent renewal
            inner = Future()
            inner.set_exception(BrokenProcessPool("the process pool was broken"))
        outer.add_done_callback(lambda o: inner.cancel() if o.cancelled() else None)

        def done(f: Future) -> None:
            if outer.done():
                return
            if f.cancelled():
                outer.cancel()
                return
            exc = f.exception()
            if exc is None:
                _settle(outer, result=f.result())
            elif isinstance(exc, BrokenProcessPool) and attempt <= self.retries and not self._closed:
                self._renew(pool)
                self._launch(outer, fn, args, kwargs, attempt + 1)
            elif isinstance(exc, BrokenProcessPool):
                _settle(
                    outer,
                    error=TaskFailed(
                        fn, args, kwargs, "its worker process died (killed or out of memory)", attempts=attempt
                    ),
                )
            else:
                _settle(outer, error=TaskFailed(fn, args, kwargs, exc, attempts=attempt))

        inner.add_done_callback(done)

    def _renew(self, broken: ProcessPoolExecutor) -> None:
        with self._lock:
            if self._pool is broken:
                self._pool = ProcessPoolExecutor(max_workers=self.workers)
        broken.shutdown(wait=False, cancel_futures=True)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        self._closed = True
        with self._lock:
            pool = self._pool
        pool.shutdown(wait=wait, cancel_futures=cancel_futures)


# --------------------------------------------------------------------------------------------- ray


def _ray():
    try:
        import ray
    except ImportError as exc:  # pragma: no cover - ray is a dependency
        raise RayUnavailable("--ray needs Ray: pip install 'ray[tune]'") from exc
    return ray


#: seconds to wait for a Ray head's port to accept a connection before ``ray.init``
RAY_CONNECT_TIMEOUT = 3.0


def check_ray_address(address: Any) -> str:
    """Refuse, in one line and within :data:`RAY_CONNECT_TIMEOUT` seconds, a ``--ray`` no cluster answers.

    Parameters
    ----------
    address : str
        ``"local"``, ``"auto"`` (a cluster started on this machine by ``ray start``), or a head's
        ``HOST:PORT`` (``ray://HOST:PORT`` for the Ray client).

    Returns
    -------
    str
        ``address``.

    Raises
    ------
    InputError
        ``address`` is empty or not of that form (a port that is not a number in 1..65535).
    RayUnavailable
        Nothing accepts a connection at ``HOST:PORT``, or no cluster runs here for ``"auto"``.
    """
    import socket

    if not isinstance(address, str) or not address.strip():
        raise InputError(f"--ray must be 'auto', 'local' or HOST:PORT of a Ray head, got {address!r}")
    if address in ("local", "auto"):
        if (
            address == "auto"
            and not os.environ.get("RAY_ADDRESS")
            and not os.path.exists("/tmp/ray/ray_current_cluster")
        ):
            raise RayUnavailable(
                "--ray auto: no Ray cluster is running on this machine (start one with `ray start --head`, "
                "or use --ray local)"
            )
        return address
    hostport = address.split("://", 1)[1] if "://" in address else address
    host, sep, port = hostport.rpartition(":")
    if not sep or not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise InputError(f"--ray must be 'auto', 'local' or HOST:PORT of a Ray head (port 1-65535), got {address!r}")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=RAY_CONNECT_TIMEOUT):
            pass
    except OSError as exc:
        why = exc.strerror or type(exc).__name__
        raise RayUnavailable(
            f"--ray {address}: no Ray head answers there ({why}); start one with `ray start --head` or use --ray local"
        ) from None
    if "://" not in address:  # a head's GCS answers its cluster id; a port of something else does not
        why = _gcs_answer(f"{host}:{port}")
        if why:
            raise RayUnavailable(
                f"--ray {address}: no Ray head answers there ({why}); start one with `ray start --head` or use "
                "--ray local"
            )
    return address


def _gcs_answer(hostport: str) -> str:
    """'' when a Ray GCS at ``hostport`` answers its cluster id within the timeout, else why not."""
    try:
        import grpc
        from ray.core.generated import gcs_service_pb2, gcs_service_pb2_grpc
    except ImportError:  # pragma: no cover - without the stubs, ray.init says it
        return ""
    channel = grpc.insecure_channel(hostport)
    try:
        stub = gcs_service_pb2_grpc.NodeInfoGcsServiceStub(channel)
        stub.GetClusterId(gcs_service_pb2.GetClusterIdRequest(), timeout=RAY_CONNECT_TIMEOUT)
    except grpc.RpcError as exc:
        return f"not a Ray head: {exc.code().name.lower()}"
    finally:
        channel.close()
    return ""


def connect_ray(address: str, *, num_cpus: int | None = None) -> bool:
    """Connect this process to Ray; returns True when it started a Ray instance itself.

    ``address``: 'auto' (a running cluster; refused in one line when none runs), 'local' (start an
    instance on this machine with ``num_cpus`` CPUs) or a head's address.
    An existing connection is reused."""
    check_ray_address(address)  # in seconds and one line, not Ray's retries and warnings
    os.environ.setdefault("RAY_BACKEND_LOG_LEVEL", "error")  # Ray's core logs to stderr otherwise
    ray = _ray()
    if ray.is_initialized():
        return False
    env = {k: os.environ[k] for k in _ENV_FORWARDED if k in os.environ}
    runtime_env = {"env_vars": env} if env else None
    kw = dict(include_dashboard=False, log_to_driver=False, logging_level="ERROR", runtime_env=runtime_env)
    if address == "local":
        ray.init(num_cpus=num_cpus, object_store_memory=256 * 2**20, **kw)
        return True
    if not address or not isinstance(address, str):
        raise RayUnavailable(f"--ray must be 'auto', 'local' or a cluster address, got {address!r}")
    try:
        ray.init(address=address, **kw)
    except ConnectionError as exc:
        where = "no Ray cluster is running on this machine" if address == "auto" else f"no Ray cluster at {address}"
        raise RayUnavailable(
            f"--ray {address}: {where} (start one with `ray start --head`, or use --ray local)"
        ) from exc
    except (ValueError, RuntimeError) as exc:
        raise RayUnavailable(f"--ray {address}: cannot connect: {_first_line(exc)}") from exc
    return False


def _call(fn: Callable, args: tuple, kwargs: dict) -> Any:
    return fn(*args, **kwargs)


_remote_call = None


def _remote():
    global _remote_call
    if _remote_call is None:
        _remote_call = _ray().remote(_call)
    return _remote_call


class RayExecutor(Executor):
    """Ray core tasks as a ``concurrent.futures.Executor``.

    ``address``: see :func:`connect_ray` (None: this process is already connected). Each task takes
    ``cpus_per_task`` CPUs (1: one task per core). Ray retries a task whose worker or node died
    ``retries`` times; an exception raised by the task becomes :class:`TaskFailed`. ``shutdown``
    stops the Ray instance when this executor started it (``'local'``)."""

    def __init__(
        self, address: str | None = "local", *, workers: int | None = None, retries: int = 2, cpus_per_task: float = 1.0
    ):
        self.address = address
        self._owns = connect_ray(address, num_cpus=workers) if address is not None else False
        if address is None and not _ray().is_initialized():  # else Ray would start an instance of its own
            raise RayUnavailable(
                "RayExecutor(None) needs a connected Ray: give an address ('local', 'auto', "
                "HOST:PORT) or call connect_ray first"
            )
        self.retries = int(retries)
        self.cpus_per_task = float(cpus_per_task)
        self._refs: dict = {}
        self._lock = threading.Lock()
        self._closed = False

    @property
    def workers(self) -> int:
        """Tasks that can run at once on the cluster (its CPUs / cpus_per_task)."""
        cpus = _ray().cluster_resources().get("CPU", 1.0)
        return max(1, int(cpus // self.cpus_per_task))

    def submit(self, fn: Callable, /, *args: Any, **kwargs: Any) -> Future:
        if self._closed:
            raise RuntimeError("cannot submit to a RayExecutor after shutdown")
        ray = _ray()
        ref = (
            _remote()
            .options(num_cpus=self.cpus_per_task, max_retries=self.retries, retry_exceptions=False)
            .remote(fn, args, kwargs)
        )
        outer: Future = Future()
        with self._lock:
            self._refs[id(outer)] = ref
        outer.add_done_callback(lambda o: ray.cancel(ref) if o.cancelled() else None)

        def done(f: Future) -> None:
            with self._lock:
                self._refs.pop(id(outer), None)
            if outer.done():
                return
            try:
                _settle(outer, result=f.result())
            except ray.exceptions.RayTaskError as exc:  # the task raised
                cause = exc.cause if getattr(exc, "cause", None) is not None else exc
                _settle(outer, error=TaskFailed(fn, args, kwargs, cause))
            except ray.exceptions.TaskCancelledError:
                outer.cancel()
            except BaseException as exc:  # worker/node died after its retries, object lost, ...
                _settle(outer, error=TaskFailed(fn, args, kwargs, exc, attempts=self.retries + 1))

        ref.future().add_done_callback(done)
        return outer

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        if self._closed:
            return
        self._closed = True
        ray = _ray()
        with self._lock:
            pending = list(self._refs.values())
        if cancel_futures:
            for ref in pending:
                ray.cancel(ref)
        elif wait and pending:
            ray.wait(pending, num_returns=len(pending))
        if self._owns:
            ray.shutdown()


# --------------------------------------------------------------------------------------------- helpers


def open_executor(ray: str | None, workers: int = 2) -> Executor | None:
    """The executor a command's ``--ray``/``--workers`` ask for.  Use it as a context manager.

    Parameters
    ----------
    ray : str or None
        ``"local"``, ``"auto"`` or a Ray address; None or empty: no Ray.
    workers : int, optional
        Processes of the local pool, or CPUs a ``"local"`` Ray instance starts.  Default 2.

    Returns
    -------
    Executor or None
        A :class:`RayExecutor` when ``ray`` is given, else a :class:`LocalExecutor` of ``workers``
        processes, or None for ``workers <= 1`` (run in this process).
    """
    if ray:
        return RayExecutor(ray, workers=workers if ray == "local" else None)
    return LocalExecutor(workers) if workers > 1 else None


def parallelism(executor: Executor | None) -> int:
    """How many tasks ``executor`` runs at once (for splitting work into chunks)."""
    if executor is None:
        return 1
    n = getattr(executor, "workers", None) or getattr(executor, "_max_workers", None)
    return int(n) if n else (os.cpu_count() or 1)


def map_ordered(
    executor: Executor | None,
    fn: Callable,
    tasks: Iterable[Sequence[Any]],
    progress: Callable[[int], None] | None = None,
    sizes: Sequence[int] | None = None,
) -> list:
    """``[fn(*t) for t in tasks]`` on ``executor`` (None: in this process), results in task order.

    Parameters
    ----------
    executor : Executor or None
        Runs the tasks; None: in this process.
    fn : callable
        The function; it and its arguments must pickle for a process pool or Ray.
    tasks : iterable of sequence
        Positional arguments of each call.
    progress : callable, optional
        ``progress(n)`` as each task completes, with ``sizes[i]``.
    sizes : sequence of int, optional
        Work units of each task for ``progress`` (default 1 each).

    Returns
    -------
    list
        The results, in task order.

    Raises
    ------
    TaskFailed
        The first failure, naming its inputs; the tasks not yet started are cancelled.
    """
    tasks = [tuple(t) for t in tasks]
    sizes = list(sizes) if sizes is not None else [1] * len(tasks)
    if executor is None:
        out = []
        for t, n in zip(tasks, sizes):
            try:
                out.append(fn(*t))
            except Exception as exc:
                raise TaskFailed(fn, t, {}, exc) from exc
            if progress is not None:
                progress(n)
        return out
    futs = [executor.submit(fn, *t) for t in tasks]
    index = {f: i for i, f in enumerate(futs)}
    try:
        for f in as_completed(futs):
            f.result()
            if progress is not None:
                progress(sizes[index[f]])
    except BaseException:
        for f in futs:
            f.cancel()
        raise
    return [f.result() for f in futs]
