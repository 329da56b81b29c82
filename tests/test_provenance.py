import platform

from pimm_agents.results.provenance import cpu_description


def test_the_cpu_and_its_widest_vector_unit_are_read_from_the_first_processor(tmp_path):
    info = tmp_path / "cpuinfo"
    first = "processor\t: 0\nmodel name\t: AMD EPYC 9R14\nflags\t\t: fpu sse4_2 avx avx2 avx512f avx512_bf16\n"
    second = "processor\t: 1\nmodel name\t: Other\nflags\t\t: fpu\n"
    info.write_text(first + "\n" + second)
    assert cpu_description(info) == ("AMD EPYC 9R14", "avx512f")
    info.write_text("processor\t: 0\nmodel name\t: Intel Xeon\nflags\t\t: fpu sse4_2 avx avx2\n")
    assert cpu_description(info) == ("Intel Xeon", "avx2")
    model, vector = cpu_description(tmp_path / "missing")  # not Linux: platform's word, no vector unit
    assert vector is None and model == (platform.processor() or None)
