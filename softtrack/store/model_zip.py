"""Model files compressed: Stable-Baselines3 and sbx write ``model.zip`` uncompressed (its
members *stored*), and most of it is base64 text of float32 parameters, which deflate halves.
:func:`deflate_model_zip` rewrites such a file with every member deflated, byte-identical
once read (the libraries read any zip method), replacing it atomically."""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

from softtrack.store.atomic import atomic_path

__all__ = ["deflate_model_zip", "is_deflated"]


def is_deflated(path: str | os.PathLike[str]) -> bool:
    """True if no member of the zip file ``path`` is stored uncompressed."""
    with zipfile.ZipFile(path) as archive:
        return all(i.compress_type != zipfile.ZIP_STORED for i in archive.infolist())


def deflate_model_zip(path: str | os.PathLike[str]) -> bool:
    """Rewrite the zip file ``path`` with every member deflated (level 9), keeping each
    member's name, date and bytes; checked by reading the new file back before it replaces the
    old one. Returns False (nothing written) if it already was.

    Raises:
        zipfile.BadZipFile: ``path`` is not a readable zip file (nothing written).
    """
    path = Path(path)
    if is_deflated(path):
        return False
    with zipfile.ZipFile(path) as archive:
        members = [(info, archive.read(info.filename)) for info in archive.infolist()]
    with atomic_path(path) as tmp:
        with zipfile.ZipFile(tmp, "w") as out:
            for info, data in members:
                entry = zipfile.ZipInfo(info.filename, date_time=info.date_time)
                entry.external_attr = info.external_attr
                out.writestr(entry, data, compress_type=zipfile.ZIP_DEFLATED, compresslevel=9)
        with zipfile.ZipFile(tmp) as check:
            if [(i.filename, check.read(i.filename)) for i in check.infolist()] != [
                (i.filename, d) for i, d in members
            ]:
                raise zipfile.BadZipFile(f"{path}: the deflated copy differs; left as it was")
    return True
