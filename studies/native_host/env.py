"""Print the environment a native FMI host needs to run an rvte FMU with this Python.

The FMU's binary (pythonfmu) embeds Python but does not link libpython itself:
the host process must preload it, and the embedded interpreter must be told its
home and where numpy and scipy are.  Output: shell `export` lines.
"""

import sys
import sysconfig
from pathlib import Path


def fmu_host_environment() -> dict:
    libdir = Path(sysconfig.get_config_var("LIBDIR"))
    library = sysconfig.get_config_var("LDLIBRARY")
    paths = [p for p in sys.path if p.endswith("site-packages")]
    return {"LD_PRELOAD": str(libdir / library), "PYTHONHOME": sys.base_prefix, "PYTHONPATH": ":".join(paths)}


if __name__ == "__main__":
    for key, value in fmu_host_environment().items():
        print(f"export {key}={value}")
