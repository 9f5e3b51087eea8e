"""A full disk for a child process: files may not grow beyond a limit."""

from __future__ import annotations

import resource
import signal


def file_size_limit(limit_bytes: int) -> None:
    """For ``subprocess.run(preexec_fn=...)``: in the child, files may not grow beyond
    ``limit_bytes`` (a write beyond fails with EFBIG, as on a full disk) and SIGXFSZ does not
    kill it."""
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))
