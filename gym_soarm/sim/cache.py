"""Files that gym_soarm derives once and keeps in the user's cache directory.

The visual meshes of both render qualities and the compiled scene models are built from packaged
sources. Each cached file is named after a digest of everything it was built from
(source bytes, settings, library versions), so a changed source or a new MuJoCo never
reads a stale file: it simply misses and builds anew.

The folder is ``$GYM_SOARM_CACHE_DIR`` when that is set (an empty value turns caching
off), otherwise the platform's user cache folder: ``$XDG_CACHE_HOME/gym_soarm`` or
``~/.cache/gym_soarm`` on Linux, ``~/Library/Caches/gym_soarm`` on macOS and
``%LOCALAPPDATA%\\gym_soarm\\Cache`` on Windows. A folder that cannot be written only
costs speed: everything is then rebuilt in memory.
"""

from __future__ import annotations

import hashlib
import logging
import os
import sys
import tempfile
from pathlib import Path

logger = logging.getLogger(__name__)

CACHE_DIR_ENV = "GYM_SOARM_CACHE_DIR"
APP_NAME = "gym_soarm"


def cache_dir() -> Path | None:
    """The folder holding gym_soarm's cached files, or None when caching is off."""
    override = os.environ.get(CACHE_DIR_ENV)
    if override is not None:
        return Path(override).expanduser() if override.strip() else None
    home = Path.home()
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA")
        return (Path(base) if base else home / "AppData" / "Local") / APP_NAME / "Cache"
    if sys.platform == "darwin":
        return home / "Library" / "Caches" / APP_NAME
    xdg = os.environ.get("XDG_CACHE_HOME", "").strip()
    return (Path(xdg) if xdg else home / ".cache") / APP_NAME


def digest(*parts: bytes | str) -> str:
    """SHA-256 hex digest of ``parts``, each length-prefixed so that they cannot run together."""
    h = hashlib.sha256()
    for part in parts:
        data = part.encode() if isinstance(part, str) else part
        h.update(len(data).to_bytes(8, "little"))
        h.update(data)
    return h.hexdigest()


def cached_path(name: str) -> Path | None:
    """Where the cached file ``name`` lives (it may not exist), or None when caching is off."""
    folder = cache_dir()
    return None if folder is None else folder / name


def read(name: str) -> bytes | None:
    """The bytes of the cached file ``name``, or None when it is absent or unreadable."""
    path = cached_path(name)
    if path is None:
        return None
    try:
        return path.read_bytes()
    except FileNotFoundError:
        return None
    except OSError as exc:
        logger.info("cannot read the cached file %s (%s); rebuilding it", path, exc)
        return None


def write(name: str, data: bytes) -> Path | None:
    """Store ``data`` as the cached file ``name``; returns its path, or None if not stored.

    The file appears atomically (written aside, then renamed), so processes that build
    the same file at the same time never read a partial one.
    """
    path = cached_path(name)
    if path is None:
        return None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(data)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
    except OSError as exc:
        logger.info("cannot write the cache file %s (%s); it will be rebuilt next time", path, exc)
        return None
    return path


def prune(pattern: str, keep: str) -> None:
    """Delete the cached files matching the glob ``pattern``, except ``keep``.

    Called after a file was rebuilt from new sources, so that superseded versions do
    not pile up. Files that cannot be deleted (in use elsewhere) are left alone.
    """
    folder = cache_dir()
    if folder is None:
        return
    for path in folder.glob(pattern):
        if path.relative_to(folder).as_posix() != keep:
            try:
                path.unlink()
            except OSError as exc:
                logger.info("cannot delete the superseded cache file %s (%s)", path, exc)
