"""Writing objects into an output directory without ever writing outside it.

Each object goes to the one safe name the reconstruction gave it (`ObjectRecord.file`: a single path
component; checked again here). Files are created relative to an open descriptor of the directory
(`dir_fd`): first under a temporary name with O_CREAT | O_EXCL | O_NOFOLLOW (a planted symlink makes the
create fail instead of being followed), then renamed over the final name, which replaces a symlink
there rather than writing through it. So whatever paths a capture holds, and whatever the directory
already holds, every byte lands in a regular file directly inside the directory. An image of a raw, BMP
or PGM format is written a second time as a PNG beside it (`write_png`), which any image viewer opens.
"""

from __future__ import annotations

import os

from mavscope.analysis.objects import IMAGE, ObjectRecord, is_plain_name
from mavscope.analysis.objects.imageformat import CONVERTED, NoPng, image_png
from mavscope.errors import UsageError

_FLAGS = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)


class ObjectWriter:
    """Writes objects and the manifest into `directory` (created if missing)."""

    def __init__(self, directory: str) -> None:
        self.directory = directory
        try:
            os.makedirs(directory, exist_ok=True)
            self.dfd = os.open(directory, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
        except OSError as exc:
            raise UsageError(f"objects: --out {directory}: {exc.strerror or exc}") from None
        self.written = 0
        self.bytes = 0

    def write(self, rec: ObjectRecord) -> str:
        """Write the object's bytes; returns its file name in the directory."""
        name = rec.file if is_plain_name(rec.file) else f"{rec.number:04d}-object"
        self._put(name, rec.data)
        self.written += 1
        self.bytes += len(rec.data)
        return name

    def write_png(self, rec: ObjectRecord) -> tuple[str | None, str | None]:
        """An image of a raw, BMP or PGM format written again as a PNG beside its file (its name with .png in
        place of its extension): (the PNG's name, None), or (None, why there is none) for an object that
        makes none (not an image, a JPEG or PNG stream, a header that does not fit)."""
        if rec.kind != IMAGE or rec.details.get("format") not in CONVERTED:
            return None, None
        try:
            data, _ = image_png(rec.details, rec.data)
        except NoPng as exc:
            return None, str(exc)
        base = rec.file if is_plain_name(rec.file) else f"{rec.number:04d}-object"
        name = base.rpartition(".")[0] + ".png" if "." in base else base + ".png"
        self._put(name, data)
        self.written += 1
        self.bytes += len(data)
        return name, None

    def write_manifest(self, data: bytes) -> str:
        self._put("manifest.json", data)
        return os.path.join(self.directory, "manifest.json")

    def _put(self, name: str, data: bytes) -> None:
        tmp = f".{name}.{os.getpid()}.tmp"
        try:
            try:
                os.unlink(tmp, dir_fd=self.dfd)  # a stale one (never followed: unlink removes the entry)
            except FileNotFoundError:
                pass
            fd = os.open(tmp, _FLAGS, 0o644, dir_fd=self.dfd)
            try:
                view = memoryview(data)
                while view:
                    view = view[os.write(fd, view):]
            finally:
                os.close(fd)
            os.replace(tmp, name, src_dir_fd=self.dfd, dst_dir_fd=self.dfd)
        except OSError as exc:
            try:
                os.unlink(tmp, dir_fd=self.dfd)
            except OSError:
                pass
            raise UsageError(f"objects: --out {self.directory}: cannot write {name}: {exc.strerror or exc}") from None

    def close(self) -> None:
        os.close(self.dfd)
