"""Run independent tasks in order, on one process or on Dask (dask.distributed).

scheduler: None or "local" runs them here, one after the other, or on `threads` threads (for
tasks whose work is in numpy and compiled calls, which release the GIL); "processes" starts a
LocalCluster with one single-threaded worker per core; anything else is the address of a
running scheduler (a real cluster). Results come back in the order of the tasks, so a
sweep gives the same numbers on any scheduler (each task carries its own seed).

A scheduler's address must be a cluster the user trusts: the tasks go there and the results
come back as pickles, which run code where they are loaded. tcp:// neither encrypts nor
authenticates; tls:// uses the credentials of Dask's own configuration (distributed.comm.tls).
The LocalCluster listens on 127.0.0.1 only, its workers too.
Dask is an extra (`pip install 'simucal[dask]'`): only the schedulers other than local import it.
"""
from __future__ import annotations

import ctypes
import os


def map_tasks(fn, tasks: list, scheduler=None, progress=None, threads: int = 1) -> list:
    """[fn(*t) for t in tasks] on the scheduler; progress wraps an iterable (e.g. tqdm)."""
    if scheduler in (None, "local"):
        if threads <= 1:
            return [fn(*t) for t in (progress(tasks) if progress else tasks)]
        from concurrent.futures import ThreadPoolExecutor

        from threadpoolctl import threadpool_limits
        # one BLAS thread each: BLAS's own threads would spin against the tasks' (a third of the speed)
        with threadpool_limits(1, "blas"), ThreadPoolExecutor(threads) as pool:
            futures = [pool.submit(fn, *t) for t in tasks]
            return [f.result() for f in (progress(futures) if progress else futures)]
    Client, LocalCluster, as_completed = _distributed("Client", "LocalCluster", "as_completed")
    if scheduler == "processes":
        cluster = LocalCluster(n_workers=os.cpu_count() or 2, threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address=None)  # Dask's default today: said, not assumed
        client = Client(cluster)
    else:
        cluster, client = None, _client(scheduler)
    try:
        futures = [client.submit(fn, *t, pure=False) for t in tasks]
        done = as_completed(futures)
        for _ in (progress(done) if progress else done):
            pass
        return client.gather(futures)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _distributed(*names: str) -> tuple:
    """The named objects of dask.distributed, or a one-line refusal naming the extra that brings Dask."""
    try:
        import dask.distributed
    except ImportError:
        from simucal.errors import CalibrationError
        raise CalibrationError("--scheduler processes or a scheduler's address runs on Dask, which is not "
                               "installed: pip install 'simucal[dask]', or use --scheduler local") from None
    return tuple(getattr(dask.distributed, n) for n in names)


def _client(address: str):
    """A Client of the scheduler at address, with the security of Dask's own configuration (or its
    security loader); a one-line refusal where none answers, or tls:// has no credentials."""
    Client, Security = _distributed("Client", "Security")
    import dask.config

    from simucal.errors import CalibrationError
    if address.startswith("tls://") and not dask.config.get("distributed.client.security-loader", None):
        security = Security()
        if not (security.tls_ca_file and security.tls_client_cert):
            raise CalibrationError(f"--scheduler {address}: Dask's configuration names no TLS credentials for a "
                                   "client; set distributed.comm.tls.ca-file, .client.cert and .client.key (in "
                                   "~/.config/dask/distributed.yaml, or DASK_DISTRIBUTED__COMM__TLS__CA_FILE "
                                   "and so on)")
    wait_s = float(os.environ.get("SIMUCAL_SCHEDULER_TIMEOUT_S", "10"))  # a slow network: more
    try:
        return Client(address, timeout=f"{wait_s:g}s")
    except (OSError, MemoryError, ValueError, TypeError) as e:  # nothing there, or a server that is not Dask
        raise CalibrationError(f"--scheduler {address}: no Dask scheduler answers there within {wait_s:g} s "
                               f"(SIMUCAL_SCHEDULER_TIMEOUT_S; {e}); start one "
                               "(dask scheduler), or use --scheduler local or processes.") from None


def keep_freed_memory():
    """Ask glibc to keep freed blocks for reuse (M_MMAP_THRESHOLD 32 MiB, its maximum; M_TRIM_THRESHOLD
    512 MiB) for the rest of the process: else every batch's temporaries of a few MiB are mapped afresh
    and page-faulted in at each allocation, a tenth of a Monte Carlo's time on two threads. For a
    process simucal owns (the command line): it is not undone (glibc's self-adjusting thresholds
    cannot be restored), so a library caller keeps its own. Nothing where the C library has no
    mallopt (macOS, Windows, musl)."""
    try:
        mallopt = getattr(ctypes.CDLL(None), "mallopt", None)
    except (OSError, TypeError):  # Windows: no process-wide C library handle
        mallopt = None
    if mallopt is not None:
        m_trim, m_mmap = -1, -3  # malloc.h's M_TRIM_THRESHOLD, M_MMAP_THRESHOLD
        mallopt(m_mmap, 32 << 20)
        mallopt(m_trim, 512 << 20)
