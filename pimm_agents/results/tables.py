"""Results as text tables: the thesis's per-scenario tables, stage timings, scored logs, rollouts, perception."""

from __future__ import annotations

from typing import Any

import numpy as np

from pimm_agents.scoring.thesis import THESIS_IOU, THESIS_RESULTS, THESIS_RETRIEVAL


def cell(value: float | None, fmt: str = ".3f", scale: float = 1.0) -> str:
    """A table cell: ``value`` (times ``scale``) in ``fmt``, or "-" where there is none."""
    return "-" if value is None else format(scale * value, fmt)


def _name_width(names: Any, least: int) -> int:
    """Column width that fits every name with two spaces to spare."""
    return max([least, *(len(n) + 2 for n in names)])


def format_tables(summary: dict[str, Any]) -> str:
    """One table per scenario, ours beside the thesis's numbers (for localizers the thesis ran)."""
    lines = []
    w = _name_width((name for rows in summary["scenarios"].values() for name in rows), 16)
    for scenario, by_localizer in summary["scenarios"].items():
        lines.append(f"\n{scenario}")
        lines.append(
            f"  {'localizer':<{w}}{'trials':>7}{'conv. rate %':>14}{'conv. time s':>14}"
            f"{'pos. err m':>12}{'ang. err deg':>14}"
        )
        for localizer, row in by_localizer.items():
            lines.append(
                f"  {localizer:<{w}}{row['trials']:>7}{100 * row['convergence_rate']:>14.0f}"
                f"{cell(row['convergence_time_s'], '.2f'):>14}{cell(row['position_error_m'], '.2f'):>12}"
                f"{cell(row['angle_error_deg'], '.2f'):>14}"
            )
            thesis = THESIS_RESULTS.get(scenario, {}).get(localizer.split("-")[0])
            if thesis is not None and localizer in ("amcl", "pimm"):
                rate, t, pos, ang = thesis
                lines.append(
                    f"  {'  thesis':<{w}}{10:>7}{100 * rate:>14.0f}{cell(t, '.2f'):>14}{cell(pos, '.2f'):>12}"
                    f"{cell(ang, '.2f'):>14}"
                )
    return "\n".join(lines)


def format_timings(summary: dict[str, Any]) -> str:
    """Mean and peak ms per stage and localizer over all scenarios (thesis section 4.6), and where the time went:
    each stage's seconds in all and their share of the localizer's ``total`` stage."""
    stages: dict[str, dict[str, list[tuple[float, float, float]]]] = {}
    for by_localizer in summary["scenarios"].values():
        for localizer, row in by_localizer.items():
            for stage, t in row["timings_ms"].items():
                entry = (t["mean"], t["max"], t.get("seconds", float("nan")))
                stages.setdefault(localizer, {}).setdefault(stage, []).append(entry)
    w = _name_width(stages, 16)
    sw = _name_width((stage for by_stage in stages.values() for stage in by_stage), 14)
    lines = [f"\n  {'localizer':<{w}}{'stage':<{sw}}{'mean ms':>10}{'peak ms':>10}{'total s':>10}{'share':>8}"]
    for localizer, by_stage in stages.items():
        whole = float(np.sum([v[2] for v in by_stage.get("total", [])])) or float("nan")
        for stage, values in by_stage.items():
            mean = float(np.mean([v[0] for v in values]))
            peak = float(np.max([v[1] for v in values]))
            seconds = float(np.sum([v[2] for v in values]))
            share = f"{100 * seconds / whole:.0f} %" if np.isfinite(seconds / whole) else "-"
            lines.append(f"  {localizer:<{w}}{stage:<{sw}}{mean:>10.2f}{peak:>10.2f}{seconds:>10.1f}{share:>8}")
    return "\n".join(lines)


def format_segmentation(scores: dict[str, Any], what: str) -> list[str]:
    """The IoU table of :func:`segmentation_scores`, with thesis table 3.2 beside it."""
    lines = [f"{'segmentation IoU, ' + what:<40}ours   thesis (table 3.2)"]
    for name in ("floor", "ceiling", "wall", "clutter"):
        lines.append(f"  {name:<38}{cell(scores['iou'][name])}   {THESIS_IOU[name]:.3f}")
    lines.append(f"  {'mean':<38}{cell(scores['miou'])}   {THESIS_IOU['mean']:.3f}")
    return lines


def format_perception(report: dict[str, Any]) -> str:
    """Readable tables of a :func:`perception_report`, with the thesis's figures beside ours."""
    lines = []
    if "segmentation" in report:
        seg = report["segmentation"]
        lines += [*format_segmentation(seg, f"{seg['scans']} fresh scans"), ""]
    if "retrieval" in report:
        ret = report["retrieval"]
        lines.append(
            "retrieval (k = 3)      queries  recall@3<2m  mean  mean-min  mean-max   thesis (k = 5, seen scans)"
        )
        rows = [*ret["per_area"].items(), ("total", ret)]
        for area, r in rows:
            thesis = THESIS_RETRIEVAL.get(area)
            ref = " / ".join(f"{v:.2f}" for v in thesis) if thesis else "-"
            lines.append(
                f"  {area:<20}{r['queries']:>7}  {r['recall_at_3_2m']:>11.3f}  {r['mean_error_m']:>4.2f}  "
                f"{r['mean_min_error_m']:>8.2f}  {r['mean_max_error_m']:>8.2f}   {ref}"
            )
        lines += [f"  suggestions passing the 10 m spread check: {ret['consistent_share']:.3f}", ""]
    headers = ("precision", "recall", "median pos. err m", "median orient. err deg")
    lines.append("corners                    " + "  ".join(f"{h:>{max(12, len(h))}}" for h in headers))
    for which, stats in report["corners"].items():
        lines.append(
            f"  {which:<24} "
            + "  ".join(f"{cell(stats[k]):>{max(12, len(h))}}" for k, h in zip(stats, headers, strict=True))
        )
    return "\n".join(lines)


def format_segment(record: dict[str, Any]) -> list[str]:
    """What ``evaluate.py segment`` found in one scan, and (with ``--reference``) how it scores."""
    how = "measured from the floor" if record["height_measured"] else "given"
    lines = [
        f"{record['file']}: {record['returns']} returns of {record['points']} points"
        + (f" ({record['left_out']} without a return left out)" if record["left_out"] else ""),
        f"  sensor {record['sensor_height_m']:.3f} m above the floor ({how}), tilted {record['tilt_deg']:.1f} deg; "
        f"{100 * record['in_network_view']:.0f} % of the returns inside the network's vertical field",
        "  classes: " + ", ".join(f"{k} {100 * v:.1f} %" for k, v in record["shares"].items()),
        f"  corners: {len(record['corners'])}"
        + "".join(f"\n    x {c['x']:7.3f}  y {c['y']:7.3f}  heading {c['theta']:6.3f} rad" for c in record["corners"]),
    ]
    if "reference" in record:
        ref = record["reference"]
        lines.append(
            "  against the plane-fit reference: IoU "
            + ", ".join(f"{k} {cell(v)}" for k, v in ref["iou"].items())
            + f"; mean {cell(ref['mean_iou'])}"
        )
        found = ref["corners"]
        lines.append(
            f"  room corners: {found['matched']} of the reference's {found['reference']} found within 0.2 m, "
            f"{found['unmatched_found']} found that match none"
        )
    lines.append(f"  written to {record['out']} (labels.npy, labelled.ply, corners.json, views.png)")
    lines += [f"warning: {text}" for text in record.get("warnings", [])]
    return lines


def format_scores(scored: list[Any], groups: dict[str, dict[str, Any]]) -> str:
    """``evaluate.py score``: a line per log, then the thesis's metrics per group."""
    lines = []
    for item in scored:
        m = item.metrics
        verdict = (
            f"converged at {m.convergence_time_s:.2f} s, error {m.position_error_m:.2f} m / {m.angle_error_deg:.1f} deg"
            if m.converged
            else "did not converge"
        )
        lines.append(f"{item.path}: {verdict}{' (from the kidnap)' if item.log.kidnap_index is not None else ''}")
    w = _name_width(groups, 12)
    lines.append(
        f"\n{'group':<{w}}{'trials':>7}{'conv. rate %':>14}{'conv. time s':>14}{'pos. err m':>12}{'ang. err deg':>14}"
        f"{'fix s':>8}{'in fix %':>9}"
    )
    for name, row in groups.items():
        lines.append(
            f"{name:<{w}}{row['trials']:>7}{100 * float(row['convergence_rate']):>14.0f}"
            f"{cell(row['convergence_time_s'], '.2f'):>14}{cell(row['position_error_m'], '.2f'):>12}"
            f"{cell(row['angle_error_deg'], '.2f'):>14}{cell(row.get('time_to_fix_s'), '.1f'):>8}"
            f"{cell(row.get('localized_share'), '.0f', 100):>9}"
        )
    return "\n".join(lines)


def format_rollouts(rollouts: dict[str, dict[str, Any]]) -> str:
    """``evaluate.py rollout``: length, time and odometry drift per scenario, beside the thesis's."""
    lines = [
        f"{'scenario':<14}{'length m':>10}{'thesis m':>10}{'time s':>9}{'thesis s':>10}{'drift m':>9}{'drift %':>9}"
        f"{'RTF':>6}  ok"
    ]
    for name, row in rollouts.items():
        ok = "yes" if row["completed"] and not row["collided"] else "NO"
        lines.append(
            f"{name:<14}{row['length_m']:>10.2f}{row['thesis_length_m'] or 0:>10.2f}{row['duration_s']:>9.1f}"
            f"{row['thesis_duration_s'] or 0:>10.2f}{cell(row['odometry_drift_m'], '.2f'):>9}"
            f"{cell(row['odometry_drift_percent'], '.2f'):>9}{row['realtime_factor']:>6.1f}  {ok}"
        )
    return "\n".join(lines)


def format_active(policies: dict[str, dict[str, Any]]) -> str:
    """``evaluate.py active``: per policy, success, time to a right localized, distance, collisions."""
    lines = [
        f"{'policy':<10}{'episodes':>9}{'success %':>10}{'median s':>9}{'p90 s':>8}{'dist. m':>9}{'collisions':>11}"
        f"{'false loc. s':>13}"
    ]
    for name, row in policies.items():
        lines.append(
            f"{name:<10}{row['episodes']:>9}{100 * row['success_rate']:>10.0f}{cell(row['median_time_s'], '.1f'):>9}"
            f"{cell(row['p90_time_s'], '.1f'):>8}{row['distance_m']:>9.1f}{row['collisions']:>11}"
            f"{row['false_localized_s']:>13.1f}"
        )
    return "\n".join(lines)


def format_run(outcome: Any) -> str:
    """``evaluate.py run``: the start, the thesis's tables, the stage timings, the trials' count and time, and
    where the results went (``outcome``: an ``experiments.experiment.Outcome``)."""
    summary = outcome.summary
    known = summary.get("start") == "known"
    reused = f" ({outcome.trials_reused} more from the earlier run)" if outcome.trials_reused else ""
    return (
        f"start: {'the true pose, nav2 initial covariance' if known else 'global (pose unknown)'}"
        f"{format_tables(summary)}\n{format_honesty(summary)}\n{format_timings(summary)}{format_collisions(summary)}\n\n"
        f"{outcome.trials_run} trials in {outcome.wall_s} s{reused}; results: {outcome.folder}/"
    )


def format_collisions(summary: dict[str, Any]) -> str:
    """A line per scenario whose robot touched an obstacle in some trial (none: ''): such a trial's route was
    not driven as planned, so its figures are not the localizer's alone."""
    lines = [
        f"  {scenario}: {entry['collisions']} of {len(entry['per_trial'])} trial(s)"
        for scenario, by in summary["scenarios"].items()
        for entry in list(by.values())[:1]  # one simulation feeds every localizer: count it once
        if entry.get("collisions")
    ]
    return "\n\ncollisions (the robot touched an obstacle on the route):\n" + "\n".join(lines) if lines else ""


def format_bench(figures: dict[str, float], machine: dict[str, Any]) -> str:
    """``evaluate.py bench``: the machine, then each figure (median ms unless its name says otherwise)."""
    cpu = f"{machine['cpu'] or 'unknown CPU'} ({machine['vector'] or 'vector unit unknown'})"
    lines = [f"machine: {cpu}, {machine['cores']} logical cores, torch {machine['torch']}"]
    return "\n".join(lines + [f"{key:<24}{value:>10.3f}" for key, value in figures.items()])


def format_replay(replay: Any, truth_topic: str) -> str:
    """``evaluate.py replay``: the thesis's tables, or where the estimates went when the bag had no truth."""
    guard = format_set_aside(replay.results)
    if not replay.has_truth:
        return f"no {truth_topic} in the bag: estimates only, in {replay.folder}/tum/<localizer>/est.tum{guard}"
    return f"{format_tables(replay.summary)}{guard}\n\nresults: {replay.folder}/"


def format_set_aside(results: Any) -> str:
    """A line per trial whose localizer's guard set observations aside or re-based the odometry (none: '')."""
    lines = [
        f"  {r.spec.name} trial {r.spec.trial}: {sum(r.log.set_aside.values())} observation(s) set aside"
        f"{_kinds(r.log.set_aside)}, {r.log.rebased} odometry re-base(s)"
        for r in results
        if r.log.set_aside or r.log.rebased
    ]
    if not lines:
        return ""
    head = (
        "\n\nset aside (by the observation guard, whose limits are the guard.* settings; before a known start;"
        " rows without a true pose, not scored):"
    )
    return head + "\n" + "\n".join(lines)


def _kinds(counts: dict[str, int]) -> str:
    return f" ({', '.join(f'{kind} {n}' for kind, n in sorted(counts.items()))})" if counts else ""


def format_honesty(summary: dict[str, Any]) -> str:
    """Does each localizer know when it is right: time to a right ``localized``, time ``localized`` while wrong
    (mean per trial, share of all localized time, longest spell, trials with none), covariance consistency, and
    for long runs the time to the first fix and the share of the time within it after (``scoring/fix.py``)."""
    w = _name_width((name for rows in summary["scenarios"].values() for name in rows), 16)
    head = (
        f"{'loc. time s':>12}{'false loc. s':>13}{'false %':>9}{'longest s':>10}{'none %':>8}{'3-sigma %':>10}"
        f"{'kidnap noticed s':>17}{'fix s':>8}{'in fix %':>9}"
    )
    lines = [f"\n  {'knowing when it is right':<{w}}{head}"]
    for scenario, by_localizer in summary["scenarios"].items():
        lines.append(f"  {scenario}")
        for name, row in by_localizer.items():
            lines.append(
                f"  {'  ' + name:<{w}}{cell(row.get('time_to_localized_s'), '.2f'):>12}"
                f"{cell(row.get('false_localized_s'), '.2f'):>13}{cell(row.get('false_localized_rate'), '.0f', 100):>9}"
                f"{cell(row.get('max_false_localized_s'), '.2f'):>10}{cell(row.get('false_free_share'), '.0f', 100):>8}"
                f"{cell(row.get('within_3sigma'), '.0f', 100):>10}{cell(row.get('kidnap_noticed_s'), '.2f'):>17}"
                f"{cell(row.get('time_to_fix_s'), '.1f'):>8}{cell(row.get('localized_share'), '.0f', 100):>9}"
            )
    return "\n".join(lines)
