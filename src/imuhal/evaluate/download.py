"""Downloading BROAD into a user cache, only when asked (``imuhal evaluate --download-broad``).

BROAD (Laidig, Caruso, Cereatti, Seel, Data 6(7), 2021; CC-BY-4.0) is never part of the
repository. The helper reads the dataset's ``trials.json`` and fetches each trial's HDF5 file
from the dataset's repository into ``<cache>/broad`` (default ``~/.cache/imuhal/broad``, or
``$XDG_CACHE_HOME/imuhal/broad``). Files already present are kept; each file appears only
when complete (written to a temporary name, then renamed).
"""

from __future__ import annotations

import json
import os
import urllib.request
from collections.abc import Callable
from pathlib import Path

from imuhal.core.atomic import AtomicFile
from imuhal.core.errors import ImuhalError

BROAD_URL = "https://raw.githubusercontent.com/dlaidig/broad/main/data_hdf5"
"""Where the HDF5 trials and their ``trials.json`` index are published."""


class DownloadError(ImuhalError):
    pass


def default_cache() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "imuhal" / "broad"


def _fetch(url: str) -> bytes:
    with urllib.request.urlopen(url, timeout=60) as r:
        return r.read()


def download_broad(cache: str | Path | None = None, *, base_url: str = BROAD_URL,
                   fetch: Callable[[str], bytes] = _fetch,
                   progress: Callable[[str], None] | None = None) -> Path:
    """Fetch BROAD's trials into ``cache`` (see module docstring); returns the folder."""
    folder = Path(cache) if cache is not None else default_cache()
    folder.mkdir(parents=True, exist_ok=True)
    try:
        index_bytes = fetch(f"{base_url}/trials.json")
        names = list(json.loads(index_bytes)["trials"])
    except (OSError, ValueError, KeyError) as exc:
        raise DownloadError(f"{base_url}/trials.json: cannot fetch BROAD's index ({exc}); "
                            "check the network or pass --broad-url") from None
    with AtomicFile(folder / "trials.json", binary=True) as f:
        f.write(index_bytes)
    for i, name in enumerate(names, 1):
        target = folder / f"{name}.hdf5"
        if target.is_file() and target.stat().st_size > 0:
            continue
        try:
            data = fetch(f"{base_url}/{name}.hdf5")
        except OSError as exc:
            raise DownloadError(f"{base_url}/{name}.hdf5: cannot fetch ({exc}); the files "
                                "fetched so far stay in " + str(folder)) from None
        with AtomicFile(target, binary=True) as f:
            f.write(data)
        if progress is not None:
            progress(f"BROAD {i}/{len(names)}: {name}")
    return folder
