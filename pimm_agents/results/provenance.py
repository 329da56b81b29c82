"""Where and with what results were made: the package version and git commit, and the machine."""

from __future__ import annotations

from pathlib import Path


def provenance() -> dict[str, str | None]:
    """The package version and the git commit (with ``+dirty`` when the tree has changes) results were made with."""
    import subprocess

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
    return {"version": installed("pimm"), "commit": commit}


def machine() -> dict[str, str | int | None]:
    """Where results were made: CPU model and widest vector extension, logical cores, OS and architecture,
    and the versions of Python, numpy and torch. PIMM's float32 paths (Embree's ray casting, the network, the
    filter's likelihoods) may round differently on CPUs with other vector units, so its trials repeat exactly
    on one CPU type, not across them (README). This is the machine that calls it: trials run on a Ray cluster
    ran on its nodes."""
    import os
    import platform

    cpu, vector = cpu_description()
    return {
        "cpu": cpu,
        "vector": vector,
        "cores": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "numpy": installed("numpy"),
        "torch": installed("torch"),
    }


def installed(distribution: str) -> str | None:
    """The installed version of ``distribution``, or None."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(distribution)
    except PackageNotFoundError:
        return None


#: Vector extensions that decide which kernels numpy, torch and Embree run, widest first (asimd: ARM's NEON).
VECTOR_EXTENSIONS = ("avx512f", "avx2", "avx", "sse4_2", "asimd")


def cpu_description(cpuinfo: Path = Path("/proc/cpuinfo")) -> tuple[str | None, str | None]:
    """The CPU's model name and its widest vector extension of ``VECTOR_EXTENSIONS``, from the first processor
    of ``cpuinfo`` (Linux); elsewhere what :func:`platform.processor` says and None."""
    import platform

    fields: dict[str, str] = {}
    try:
        for line in cpuinfo.read_text().splitlines():
            if not line.strip() and fields:
                break  # the first processor's block is enough
            key, _, value = line.partition(":")
            fields.setdefault(key.strip(), value.strip())
    except OSError:
        pass
    model = fields.get("model name") or platform.processor() or None
    flags = set((fields.get("flags") or fields.get("Features") or "").split())
    return model, next((v for v in VECTOR_EXTENSIONS if v in flags), None)
