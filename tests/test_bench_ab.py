"""bench/ab_load.py's arithmetic: the figures of a bench_load result and the paired
differences (the runs themselves are a benchmark, not a test)."""

import json
import textwrap

from bench.ab_load import figures, one_run, paired


def _result(posed_per_s, delivered, cpu_ms, offered=100, bound=20.0):
    run = {"posed_per_s": posed_per_s, "delivered": delivered, "offered": offered,
           "unaccounted": 0, "p50_ms": 1500.0, "p99_ms": 4000.0,
           "breakdown": [{"process": "h0", "cpu_ms": 1.0}, {"process": "ALL", "cpu_ms": cpu_ms}]}
    return {"runs": [run], **({"bound": {"photos_per_s": bound}} if bound else {})}


def test_figures_are_per_cpu_second_and_against_the_runs_bound():
    f = figures(_result(10.0, 50, 40.0))      # 100 photos x 40 ms = 4 CPU s for 50 posed
    assert f["posed_per_cpu_s"] == 12.5 and f["share_of_bound"] == 0.5
    assert (f["pose_p50_s"], f["pose_p99_s"]) == (1.5, 4.0)   # photo -> pose, seconds
    assert figures(_result(10.0, 50, 40.0, bound=None))["share_of_bound"] is None


def test_paired_differences_are_b_minus_a_per_pair_with_the_wins_counted():
    a = [figures(_result(p, 50, 40.0)) for p in (10.0, 12.0, 11.0)]
    b = [figures(_result(p, 50, 40.0)) for p in (11.0, 11.5, 13.0)]
    line = next(x for x in paired(a, b) if x.startswith("posed_per_s"))
    assert "+1.000 -0.500 +2.000" in line and "B higher in 2 of 3" in line
    assert "median +1.000" in line


def test_a_run_serves_the_code_of_its_own_tree(tmp_path, monkeypatch):
    """The services bench_load starts run ``python -m``, which imports from the working
    directory first: a run of tree A started from tree B must still serve A's code."""
    trees = {}
    for name in ("a", "b"):
        t = trees[name] = tmp_path / name
        (t / "bench").mkdir(parents=True)
        (t / "probe_mod.py").write_text(f"print({name!r})\n")
        # as bench_load's Deployment starts a service: ``python -m``, inheriting cwd and env
        (t / "bench" / "bench_load.py").write_text(textwrap.dedent(f"""
            import json, subprocess, sys
            out = sys.argv[sys.argv.index("--json") + 1]
            served = subprocess.run([sys.executable, "-m", "probe_mod"], text=True,
                                    capture_output=True, check=True).stdout.strip()
            json.dump({{"runs": [{{"posed_per_s": 1.0, "delivered": 1, "offered": 1,
                       "unaccounted": 0, "p50_ms": 1.0, "p99_ms": 1.0, "served": served,
                       "breakdown": [{{"process": "ALL", "cpu_ms": 1.0}}]}}]}}, open(out, "w"))
            print("1 photos")
            """))
    monkeypatch.chdir(trees["b"])          # ab_load runs from B's tree
    out = tmp_path / "a.json"
    assert one_run(trees["a"], "peak", {}, out)["photos"] == "1 photos"
    assert json.loads(out.read_text())["runs"][0]["served"] == "a"


def test_keep_holds_every_runs_result_with_bs_environment(tmp_path, monkeypatch):
    """``--keep DIR``: each run's bench_load --json is kept (A0, B0, A1, B1, ...), so the
    per-process breakdown of every run can be read afterwards; B's runs had ``--env-b``."""
    import bench.ab_load as ab
    tree = tmp_path / "tree"
    (tree / "bench").mkdir(parents=True)
    (tree / "bench" / "bench_load.py").write_text(textwrap.dedent("""
        import json, os, sys
        out = sys.argv[sys.argv.index("--json") + 1]
        json.dump({"runs": [{"posed_per_s": 1.0, "delivered": 1, "offered": 1,
                   "unaccounted": 0, "p50_ms": 1.0, "p99_ms": 1.0,
                   "knob": os.environ.get("AB_KNOB", ""),
                   "breakdown": [{"process": "ALL", "cpu_ms": 1.0}]}]}, open(out, "w"))
        print("1 photos")
        """))
    monkeypatch.setattr(ab, "HERE", tree)
    keep = tmp_path / "kept"
    assert ab.main(["--env-b", "AB_KNOB=1", "--pairs", "2", "--keep", str(keep)]) == 0
    assert sorted(p.name for p in keep.iterdir()) == ["A0.json", "A1.json", "B0.json", "B1.json"]
    knobs = {p.stem: json.loads(p.read_text())["runs"][0]["knob"] for p in keep.iterdir()}
    assert knobs == {"A0": "", "A1": "", "B0": "1", "B1": "1"}
