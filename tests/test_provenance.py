from pimm_agents.evaluation.provenance import cpu_model


def test_the_cpu_model_is_read_from_cpuinfo_and_a_missing_file_falls_back(tmp_path):
    info = tmp_path / "cpuinfo"
    info.write_text("processor\t: 0\nvendor_id\t: AuthenticAMD\nmodel name\t: AMD EPYC 9R14\nflags\t\t: fpu avx512f\n")
    assert cpu_model(info) == "AMD EPYC 9R14"
    fallback = cpu_model(tmp_path / "missing")
    assert fallback is None or (isinstance(fallback, str) and fallback)
