"""PIMM's benchmark suites, read from ``training/suites/suites.yaml``: named sets of buildings (or commands) with
what each measures, so that a held-out set is chosen by what it judges, not by the experiment that made it."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

from pimm_env.errors import PimmError
from pimm_env.yaml_file import read_yaml_mapping

SUITES_FILE = Path(__file__).parent / "suites" / "suites.yaml"
KINDS = ("training", "development", "held-out", "reference")


class SuiteError(PimmError):
    """A suite that does not exist or is written wrong."""


@dataclass(frozen=True)
class Suite:
    name: str
    kind: str  # one of KINDS
    purpose: str
    seeds: tuple[int, ...] = ()  # generated buildings (training/buildings.py)
    localizers: tuple[str, ...] = ("pimm",)
    trials: int = 1
    commands: tuple[tuple[str, ...], ...] = field(default=())  # evaluate.py commands, for suites of other data
    benchmark: str = "localize"  # what is measured on the buildings: localize (heldout.py) or cloud-maps


def parse_seeds(ranges: list[str] | tuple[str, ...], where: str = "seeds") -> tuple[int, ...]:
    """``["100-129", "140"]`` as the seeds it names, in order."""
    seeds: list[int] = []
    for item in ranges:
        text = str(item).strip()
        low, _, high = text.partition("-")
        try:
            first, last = int(low), int(high or low)
        except ValueError:
            raise SuiteError(f"{where}: {item!r} is not a seed or a range A-B") from None
        if last < first:
            raise SuiteError(f"{where}: {item!r} runs backwards")
        seeds += range(first, last + 1)
    return tuple(seeds)


@cache
def suites(path: Path = SUITES_FILE) -> dict[str, Suite]:
    """Every suite of the suites file, by name."""
    data = read_yaml_mapping(path, "suites file", SuiteError)
    if data.get("format") != "pimm-suites/1" or not isinstance(data.get("suites"), dict):
        raise SuiteError(f"{path}: expected 'format: pimm-suites/1' and a 'suites' mapping")
    out = {}
    for name, body in data["suites"].items():
        where = f"{path}: suites.{name}"
        if not isinstance(body, dict) or body.get("kind") not in KINDS or not body.get("purpose"):
            raise SuiteError(f"{where}: needs a 'purpose' and a 'kind' of {', '.join(KINDS)}")
        commands = tuple(tuple(str(a) for a in c) for c in body.get("commands", ()))
        seeds = parse_seeds(body.get("seeds", ()), f"{where}.seeds")
        if bool(seeds) == bool(commands):
            raise SuiteError(f"{where}: give either 'seeds' (generated buildings) or 'commands', not both or neither")
        localizers = tuple(body.get("localizers", ("pimm",)))
        benchmark = str(body.get("benchmark", "localize"))
        if benchmark not in ("localize", "cloud-maps"):
            raise SuiteError(f"{where}.benchmark: expected localize or cloud-maps, got {benchmark!r}")
        trials = int(body.get("trials", 1))
        out[name] = Suite(name, body["kind"], body["purpose"], seeds, localizers, trials, commands, benchmark)
    return out


def suite(name: str) -> Suite:
    """The suite called ``name``; a clear error listing them otherwise."""
    known = suites()
    if name not in known:
        raise SuiteError(f"no suite {name!r}; suites: {', '.join(known)}")
    return known[name]


def seeds_of(kind: str) -> tuple[int, ...]:
    """The seeds of every suite of ``kind``, in the file's order."""
    return tuple(s for x in suites().values() if x.kind == kind for s in x.seeds)


def subset(chosen: Suite, seeds: list[int] | None) -> tuple[int, ...]:
    """The suite's buildings, or only ``seeds`` of them (each must be the suite's)."""
    if seeds is None:
        return chosen.seeds
    outside = sorted(set(seeds) - set(chosen.seeds))
    if outside:
        raise SuiteError(f"seeds {outside} are not buildings of suite {chosen.name!r}")
    return tuple(s for s in chosen.seeds if s in set(seeds))
