"""The result pages and their index: ``benchmarks/_results.py`` writes one page per section,
with its command, date, commit, machine and summary, and keeps ``docs/RESULTS.md`` generated
from the pages, also under concurrent writers.

The module is loaded the way ``pushbot eval perception|estimator --write`` loads it: from its
file, without registering it in ``sys.modules``.
"""

from __future__ import annotations

import importlib.util
import json
import re
import subprocess
import sys
import textwrap
from pathlib import Path
from types import ModuleType

import pytest

REPO = Path(__file__).resolve().parents[1]
COMMIT = re.compile(r"^([0-9a-f]{4,40}(-dirty)?|unknown)$")


def _load() -> ModuleType:
    spec = importlib.util.spec_from_file_location("_results_under_test",
                                                  REPO / "benchmarks" / "_results.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


results = _load()


def _section(title: str, body: str) -> str:
    return results.format_section(title, "python benchmarks/bench_x.py --n 3", body,
                                  date="2026-01-02", machine="test machine")


def test_a_section_becomes_a_page_and_a_row_of_the_index(tmp_path: Path) -> None:
    index = tmp_path / "docs" / "RESULTS.md"
    page = results.update_section("bench_x", _section("Speed (`bench_x`)", "| a |\n| --- |\n"),
                                  index, summary="How fast x is.")
    assert page == tmp_path / "docs" / "results" / "bench_x.md"
    text = page.read_text()
    assert text.startswith("# Speed (`bench_x`)\n")
    assert "[results index](../RESULTS.md)" in text
    fields = results.parse_section("bench_x", text).fields
    assert fields["command"] == "`python benchmarks/bench_x.py --n 3`"
    assert fields["date"] == "2026-01-02" and fields["machine"] == "test machine"
    assert fields["summary"] == "How fast x is." and COMMIT.match(fields["commit"]), fields
    assert text.rstrip().endswith("| a |\n| --- |")
    row = "| [Speed (`bench_x`)](results/bench_x.md) | How fast x is. | 2026-01-02 | "
    assert row + fields["commit"] + " |" in index.read_text()


def test_rewriting_a_page_keeps_its_summary_and_the_other_pages(tmp_path: Path) -> None:
    index = tmp_path / "RESULTS.md"
    results.update_section("eval_a", _section("A", "First text. More."), index,
                           summary="What A is.")
    results.update_section("zz_new", _section("New", "Measured z. Then more."), index,
                           commit="abc1234", data="`z.json`, rendered by `python z.py --render`")
    results.update_section("eval_a", _section("A", "Second text."), index)
    a = results.parse_section("eval_a", results.page_path("eval_a", index).read_text())
    assert a.fields["summary"] == "What A is." and a.body == "Second text."
    new = results.parse_section("zz_new", results.page_path("zz_new", index).read_text())
    assert new.fields["summary"] == "Measured z." and new.fields["commit"] == "abc1234"
    assert new.fields["data"] == "`z.json`, rendered by `python z.py --render`"
    text = index.read_text()
    assert "## Other results" in text  # a section id no group names
    assert text.index("results/eval_a.md") < text.index("results/zz_new.md")
    results.update_section("eval_a", _section("A", "Third."), index, summary="Now this.")
    assert "| Now this. |" in index.read_text()


def test_bad_section_ids_are_refused(tmp_path: Path) -> None:
    for bad in ("", "a b", "../x", "a/b"):
        with pytest.raises(ValueError, match="section_id"):
            results.update_section(bad, _section("T", "x"), tmp_path / "RESULTS.md")
    assert not (tmp_path / "results").exists()


def test_concurrent_writers_lose_no_page_and_no_row(tmp_path: Path) -> None:
    index = tmp_path / "RESULTS.md"
    module = str(REPO / "benchmarks" / "_results.py")
    script = textwrap.dedent(f"""
        import importlib.util, sys
        spec = importlib.util.spec_from_file_location("r", {module!r})
        r = importlib.util.module_from_spec(spec); spec.loader.exec_module(r)
        for i in range(10):
            sid = f"{{sys.argv[1]}}_{{i}}"
            text = f"## {{sid}}\\n\\n- command: `x`\\n- date: d\\n- machine: m\\n\\nbody"
            r.update_section(sid, text, {str(index)!r}, summary=sid, commit="c0ffee0")
    """)
    procs = [subprocess.Popen([sys.executable, "-c", script, name]) for name in ("p", "q", "r")]
    assert [p.wait(timeout=120) for p in procs] == [0, 0, 0]
    ids = {f"{name}_{i}" for name in "pqr" for i in range(10)}
    assert {p.stem for p in (tmp_path / "results").glob("*.md")} == ids
    rows = set(re.findall(r"\(results/(\w+)\.md\)", index.read_text()))
    assert rows == ids


def test_the_committed_index_is_generated_from_the_committed_pages() -> None:
    pages = results.read_pages()
    assert len(pages) >= 38
    assert (REPO / "docs" / "RESULTS.md").read_text() == results.render_index(pages), \
        "docs/RESULTS.md is stale: python benchmarks/_results.py --index"
    for page in pages:
        missing = {"command", "date", "commit", "machine", "summary"} - set(page.fields)
        assert not missing, f"docs/results/{page.section_id}.md has no {sorted(missing)}"
        assert re.fullmatch(r"\d{4}-\d{2}-\d{2}", page.fields["date"]), page.section_id


def test_a_benchmark_saves_its_figures_and_renders_its_page_from_them(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    spec = importlib.util.spec_from_file_location("time_tests_under_test",
                                                  REPO / "benchmarks" / "time_tests.py")
    assert spec is not None and spec.loader is not None
    time_tests = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(time_tests)
    monkeypatch.setattr(time_tests._results, "RESULTS_PATH", tmp_path / "RESULTS.md")
    # The machine line imports torch for its version (seconds); this test is about the files.
    monkeypatch.setattr(time_tests._results, "machine_info", lambda: "test machine")
    log = tmp_path / "cc1.log"
    log.write_text("== 2 failed, 9 passed, 1 warning in 61.5s ==\nreal\t2m3.5s\n")
    assert time_tests.main(["--tiers", "--ci-log", str(log)]) == 0  # reads the log, runs no tier
    record = json.loads((tmp_path / "results" / "test_tiers.json").read_text())
    assert record["figures"][0]["counts"] == {"failed": 2, "passed": 9}
    assert record["command"] == "python benchmarks/time_tests.py --tiers --ci-log cc1.log"
    page = tmp_path / "results" / "test_tiers.md"
    first = page.read_text()
    assert ("| full | `.ci/run` on a clean clone (cc1.log; 2.1 min with the venv build) | "
            "1.0 min | 1 | 2 failed, 9 passed | - |") in first
    fields = results.parse_section("test_tiers", first).fields
    assert fields["data"] == ("[`test_tiers.json`](test_tiers.json), rendered by "
                              "`python benchmarks/time_tests.py --render`")
    assert (fields["date"], fields["commit"], fields["machine"]) == (
        record["date"], record["commit"], "test machine")
    page.write_text("stale\n")
    assert time_tests.main(["--render"]) == 0
    assert page.read_text() == first


def test_sections_of_the_old_single_file_format_become_pages(tmp_path: Path) -> None:
    index = tmp_path / "RESULTS.md"
    results.update_section("kept", _section("Kept", "Already a page."), index, summary="Kept.")
    old = "\n\n".join(f"<!-- BEGIN {sid} -->\n{_section(sid.title(), f'{sid} figures.')}\n"
                      f"<!-- END {sid} -->" for sid in ("kept", "new_a", "new_b"))
    assert results.import_sections("# pushbot results\n\n" + old, path=index) == ["new_a",
                                                                                  "new_b"]
    a = results.parse_section("new_a", results.page_path("new_a", index).read_text())
    assert (a.title, a.body, a.fields["date"]) == ("New_A", "new_a figures.", "2026-01-02")
    assert a.fields["commit"] == "not recorded (imported)"
    kept = results.parse_section("kept", results.page_path("kept", index).read_text())
    assert kept.body == "Already a page."
    assert results.import_sections(old, ["kept"], commit="1234abc", path=index) == ["kept"]
    kept = results.parse_section("kept", results.page_path("kept", index).read_text())
    assert (kept.body, kept.fields["commit"], kept.fields["summary"]) == (
        "kept figures.", "1234abc", "Kept.")
    with pytest.raises(ValueError, match="no such section"):
        results.import_sections(old, ["gone"], path=index)
    assert set(re.findall(r"\(results/(\w+)\.md\)", index.read_text())) == {"kept", "new_a",
                                                                            "new_b"}
