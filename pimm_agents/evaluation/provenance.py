"""Where and with what results were made: the package version and git commit, and the machine."""

from __future__ import annotations

from pathlib import Path


def provenance() -> dict[str, str | None]:
    """The package version and the git commit (with ``+dirty`` when the tree has changes) results were made with."""
    import subprocess
    from importlib.metadata import PackageNotFoundError, version

    try:
        package = version("pimm")
    except PackageNotFoundError:
        package = None
    root = Path(__file__).resolve().parents[2]
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                               capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
        commit += "+dirty" if dirty else ""
    except (OSError, subprocess.CalledProcessError):
        commit = None
    return {"version": package, "commit": commit}


def machine() -> dict[str, str | int | None]:
    """Where results were made: CPU model, logical cores, OS and architecture, and the versions of Python,
    numpy and torch. PIMM's float32 paths (the network, the filter's likelihoods) round differently on CPUs
    with other vector units, so its trials repeat exactly on one CPU type, not across them (README)."""
    import os
    import platform
    from importlib.metadata import PackageNotFoundError, version

    def installed(name: str) -> str | None:
        try:
            return version(name)
        except PackageNotFoundError:
            return None

    return {
        "cpu": cpu_model(),
        "cores": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "numpy": installed("numpy"),
        "torch": installed("torch"),
    }


def cpu_model(cpuinfo: Path = Path("/proc/cpuinfo")) -> str | None:
    """The CPU's model name from ``cpuinfo`` (Linux), else what :func:`platform.processor` says (None if
    nothing)."""
    import platform

    try:
        for line in cpuinfo.read_text().splitlines():
            key, _, value = line.partition(":")
            if key.strip() == "model name" and value.strip():
                return value.strip()
    except OSError:
        pass
    return platform.processor() or None
