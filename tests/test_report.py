from pimm_agents.results.tables import format_tables, format_timings


def test_tables_keep_their_columns_for_long_localizer_and_stage_names():
    timing = {"mean": 1.0, "max": 2.0, "seconds": 0.25}
    row = {
        "trials": 3,
        "convergence_rate": 2 / 3,
        "convergence_time_s": 12.5,
        "position_error_m": 0.1,
        "angle_error_deg": 1.5,
        "timings_ms": {"measurement_update": timing, "total": dict(timing, seconds=1.0)},
    }
    summary = {"scenarios": {"area_b": {"amcl": row, "amcl-recovery-nav2": row}}}
    table = format_tables(summary).splitlines()
    rows = [line for line in table if line.strip().startswith(("localizer", "amcl", "thesis"))]
    assert len(rows) == 4  # header, amcl, the thesis's AMCL, and the variant
    assert len({len(line) for line in rows}) == 1  # right-aligned columns end in the same place
    assert "amcl-recovery-nav2  " in table[-1] and table[-1].split()[1:] == ["3", "67", "12.50", "0.10", "1.50"]
    timings = [line for line in format_timings(summary).splitlines() if line.strip()]
    assert len({len(line) for line in timings}) == 1  # every column lines up
    assert "measurement_update  " in timings[1]
    assert timings[1].split()[-3:] == ["0.2", "25", "%"]  # its seconds in all, and its share of the total's
