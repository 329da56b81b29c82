"""A results folder as Markdown for the docs (``evaluate.py report RESULTS_DIR --markdown``): one table per
results folder, headed by the command, commit and machine that made it, so a table in the docs says where it
came from."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pimm_agents.results.tables import cell
from pimm_agents.scoring.thesis import THESIS_IOU, THESIS_RESULTS, THESIS_RETRIEVAL
from pimm_env.errors import MissingFileError, ResultsError

COLUMNS = ("trials", "conv. rate %", "conv. time s", "pos. err m", "ang. err deg")


def read_summary(folder: Path) -> dict[str, Any]:
    """A results folder's ``summary.json``; errors name the file."""
    path = Path(folder) / "summary.json"
    if not path.is_file():
        raise MissingFileError(f"{path}: no summary.json: is {folder} a results folder of run, sweep or replay?")
    try:
        summary = json.loads(path.read_text())
    except json.JSONDecodeError as error:
        raise ResultsError(f"{path}: not JSON ({error})") from None
    if not isinstance(summary, dict) or not isinstance(summary.get("scenarios"), dict):
        raise ResultsError(f"{path}: no 'scenarios' mapping: not a summary written by evaluate.py")
    return summary


def provenance_line(summary: dict[str, Any]) -> str:
    """Which command, commit and machine made the results."""
    made = summary.get("run", {})
    command = made.get("command") or made.get("repeat") or "(command not recorded)"
    machine = summary.get("machine") or {}
    cpu = machine.get("cpu") or "unknown CPU"
    cores = machine.get("cores")
    where = f"{cpu}, {cores} logical cores" if cores else cpu
    commit = summary.get("commit") or "unknown commit"
    return f"Made by `{command}` at commit `{commit}` (pimm {summary.get('version', '?')}) on {where}."


def results_table(scenarios: dict[str, dict[str, Any]], thesis: bool = True) -> list[str]:
    """One Markdown table of every scenario and localizer, the thesis's row (italic) under each localizer it
    ran."""
    lines = ["| scenario | localizer | " + " | ".join(COLUMNS) + " |", "|---|---|" + "---:|" * len(COLUMNS)]
    for scenario, rows in scenarios.items():
        for k, (name, row) in enumerate(rows.items()):
            cells = (
                str(row["trials"]),
                cell(row["convergence_rate"], ".0f", 100),
                cell(row["convergence_time_s"], ".2f"),
                cell(row["position_error_m"], ".3f"),
                cell(row["angle_error_deg"], ".2f"),
            )
            first = f" {scenario} " if k == 0 else " "
            lines.append(f"|{first}| {name} | " + " | ".join(cells) + " |")
            reference = THESIS_RESULTS.get(scenario, {}).get(name) if thesis else None
            if reference is not None:
                rate, t, pos, ang = reference
                cells = ("10", cell(rate, ".0f", 100), cell(t, ".2f"), cell(pos, ".3f"), cell(ang, ".2f"))
                lines.append(f"| | *{name}, thesis* | " + " | ".join(f"*{c}*" for c in cells) + " |")
    return lines


def honesty_table(scenarios: dict[str, dict[str, Any]]) -> list[str]:
    """Whether each localizer knew when it was right (docs/evaluation.md): one Markdown table."""
    columns = (
        "time to localized s",
        "false localized s",
        "false %",
        "longest s",
        "trials without %",
        "3-sigma %",
        "kidnap noticed s",
        "fix s",
        "in fix %",
    )
    lines = ["| scenario | localizer | " + " | ".join(columns) + " |", "|---|---|" + "---:|" * len(columns)]
    for scenario, rows in scenarios.items():
        for k, (name, row) in enumerate(rows.items()):
            cells = (
                cell(row.get("time_to_localized_s"), ".2f"),
                cell(row.get("false_localized_s"), ".2f"),
                cell(row.get("false_localized_rate"), ".0f", 100),
                cell(row.get("max_false_localized_s"), ".2f"),
                cell(row.get("false_free_share"), ".0f", 100),
                cell(row.get("within_3sigma"), ".0f", 100),
                cell(row.get("kidnap_noticed_s"), ".2f"),
                cell(row.get("time_to_fix_s"), ".1f"),
                cell(row.get("localized_share"), ".0f", 100),
            )
            lines.append(f"|{f' {scenario} ' if k == 0 else ' '}| {name} | " + " | ".join(cells) + " |")
    return lines


def markdown_report(folder: Path, thesis: bool = True) -> str:
    """The folder's results as Markdown, after a line naming the command, commit and machine: the thesis's
    metrics, and whether each localizer knew when it was right (where the summary has those figures)."""
    summary = read_summary(folder)
    lines = [provenance_line(summary), "", *results_table(summary["scenarios"], thesis)]
    rows = [row for by in summary["scenarios"].values() for row in by.values()]
    if rows and "false_localized_s" in rows[0]:
        lines += ["", *honesty_table(summary["scenarios"])]
    return "\n".join(lines) + "\n"


def text_report(folder: Path) -> str:
    """The folder's tables as ``evaluate.py run`` prints them, after the provenance line."""
    from pimm_agents.results.tables import format_tables

    summary = read_summary(folder)
    return f"{provenance_line(summary)}\n{format_tables(summary)}\n"


def provenance_here(command: str) -> str:
    """The provenance line for figures made now, in this process: ``command``, this checkout's commit, this
    machine."""
    from pimm_agents.results.provenance import machine, provenance

    return provenance_line({"run": {"command": command}, **provenance(), "machine": machine()})


def perception_markdown(report: dict[str, Any], command: str) -> str:
    """``evaluate.py perception --markdown``: segmentation IoU, retrieval and corners as Markdown tables."""
    lines = [provenance_here(command), ""]
    if "segmentation" in report:
        seg = report["segmentation"]
        names = list(seg["iou"])
        lines += ["| IoU | " + " | ".join(names) + " | mean |", "|---|" + "---:|" * (len(names) + 1)]
        ours = " | ".join(f"{seg['iou'][n]:.3f}" for n in names)
        thesis = " | ".join(f"*{THESIS_IOU[n]:.3f}*" for n in names)
        lines.append(f"| ours | {ours} | **{seg['miou']:.3f}** |")
        lines += [f"| *thesis, table 3.2* | {thesis} | *{THESIS_IOU['mean']:.2f}* |", ""]
    if "retrieval" in report:
        ret = report["retrieval"]
        header = "| retrieval, k = 3 | queries | recall@3 < 2 m | mean m | mean-min m | mean-max m | thesis (k = 5) |"
        lines += [header, "|---|---:|---:|---:|---:|---:|---|"]
        for area, r in [*ret["per_area"].items(), ("total", ret)]:
            reference = THESIS_RETRIEVAL.get(area)
            lines.append(
                f"| {area} | {r['queries']} | {r['recall_at_3_2m']:.2f} | {r['mean_error_m']:.2f} | "
                f"{r['mean_min_error_m']:.2f} | {r['mean_max_error_m']:.2f} | "
                + (" / ".join(f"{v:.2f}" for v in reference) if reference else "-")
                + " |"
            )
        lines.append("")
    lines += ["| corners, labels | precision | recall | median position error m | median orientation error ° |"]
    lines.append("|---|---:|---:|---:|---:|")
    for which, stats in report["corners"].items():
        cells = [cell(stats[k], f) for k, f in zip(stats, (".2f", ".2f", ".3f", ".2f"), strict=True)]
        lines.append(f"| {which.replace('_labels', '')} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def bench_markdown(figures: dict[str, float], command: str) -> str:
    """``evaluate.py bench --markdown``: every figure of one run as a Markdown table."""
    lines = [provenance_here(command), "", "| figure | median |", "|---|---:|"]
    lines += [f"| `{key}` | {value:.3f} |" for key, value in figures.items()]
    return "\n".join(lines) + "\n"


def _object_errors_markdown(world: str, objects: list[dict[str, Any]], classes: tuple[str, ...]) -> list[str]:
    """The objects of ``world`` whose returns were labelled wrong most often, one row each."""
    lines = [f"Objects of {world} labelled wrong most often (returns labelled each class):", ""]
    lines += ["| object | class | returns | wrong | " + " | ".join(classes) + " |", "|---|---|" + "---:|" * 6]
    for row in objects:
        counts = " | ".join(str(row["labelled"][name]) for name in classes)
        lines.append(f"| `{row['name']}` | {row['class']} | {row['returns']} | {row['wrong']} | {counts} |")
    return [*lines, ""]


def perception_table_markdown(table: dict[str, Any], command: str) -> str:
    """``evaluate.py perception-table``: real scans, worlds and LiDAR layouts as Markdown tables."""
    classes = ("wall", "ceiling", "floor", "clutter")
    lines = [provenance_here(command), "", f"Weights: `{table['weights']}`.", ""]

    def row(name: str, scores: dict[str, Any], extra: str = "") -> str:
        ious = " | ".join(cell(scores["iou"].get(k)) for k in classes)
        return f"| {name} | {ious} | **{cell(scores.get('mean_iou', scores.get('miou')))}** |{extra}"

    header = "| IoU | " + " | ".join(classes) + " | mean |"
    if table["real_scans"]:
        lines += [header + " room corners within 0.2 m |", "|---|" + "---:|" * 5 + "---:|"]
        for path, scores in table["real_scans"].items():
            found = scores["corners"]
            lines.append(
                row(
                    f"`{Path(path).name}` (plane-fit reference)",
                    scores,
                    f" {found['matched']} of {found['reference']} |",
                )
            )
        lines.append("")
    if table["worlds"]:
        lines += [header, "|---|" + "---:|" * 5]
        for world, scores in table["worlds"].items():
            lines.append(
                row(
                    f"{Path(world).parent.name if world.endswith('.yaml') else world} ({scores['scans']} scans)", scores
                )
            )
        lines.append("")
        for world, scores in table["worlds"].items():
            if scores.get("objects"):
                lines += _object_errors_markdown(world, scores["objects"], classes)
    if "layouts" in table:
        layouts = table["layouts"]
        lines += [f"Every layout in {layouts['world']} ({table['scans_per_world']} scans each), mean IoU:", ""]
        lines += ["| layout @ mount | height measured | height given | height error m |", "|---|---:|---:|---:|"]
        for key, measured in layouts["measured"].items():
            given = layouts["given"][key]
            lines.append(f"| {key} | {measured['miou']:.3f} | {given['miou']:.3f} | {measured['height_error_m']:.3f} |")
        lines.append("")
    return "\n".join(lines)
