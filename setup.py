"""Build glue that pyproject.toml cannot express: the optional C extension and the shipped dialects.

- `mavscope._native` (src/mavscope_native/*.c): the native fast path. `optional=True`: when it cannot
  be compiled (no compiler, no Python headers) the install goes on and mavscope runs pure Python.
- `dissectors/*.xml` are copied into the package (mavscope/dissectors), where
  mavscope.mavlink.dialect.default_dissectors_dir() finds them in an installed wheel.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent
NATIVE = Path("src") / "mavscope_native"
SOURCES = ["module.c", "walk.c", "capture.c", "capture_pcap.c", "capture_pcapng.c", "capture_tlog.c",
           "netlayers.c", "mavlink.c", "table.c", "decode.c", "fmt.c", "buf.c", "summary.c", "columns.c",
           "recv.c", "module_recv.c", "module_fields.c", "sha256.c", "signing.c"]
# -ffp-contract=off: the JSON and summary formatters' float arithmetic as Python's (no fused multiply-add)
CFLAGS = [] if sys.platform == "win32" else ["-std=c11", "-O2", "-Wall", "-Wextra", "-ffp-contract=off"]


class BuildPyWithDissectors(build_py):
    """build_py, plus dissectors/*.xml into mavscope/dissectors of the build."""

    def run(self) -> None:
        super().run()
        if self.editable_mode:  # an editable install finds them in the checkout (default_dissectors_dir)
            return
        target = Path(self.build_lib) / "mavscope" / "dissectors"
        target.mkdir(parents=True, exist_ok=True)
        for xml in sorted((ROOT / "dissectors").glob("*.xml")):
            shutil.copy2(xml, target / xml.name)


setup(
    ext_modules=[
        Extension(
            "mavscope._native",
            sources=[str(NATIVE / s) for s in SOURCES],
            include_dirs=[str(NATIVE)],
            extra_compile_args=CFLAGS,
            optional=True,
        )
    ],
    cmdclass={"build_py": BuildPyWithDissectors},
)
