"""Sweeps within what the machine holds (issue #46, item 5): one sweep per folder, a grid or
member count and a worker count bounded by the memory (one line with the numbers, --force
to go on), seeds a 64-bit integer holds."""

from pathlib import Path

import pytest

from spinweb_fe.cli import main

CASES = Path(__file__).parent.parent / "cases"
GIB = 2 ** 30


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def sweep_file(tmp_path, body, base="demo.toml", mode="fe"):
    p = tmp_path / "sweep.toml"
    p.write_text(f'base = "{CASES / base}"\nmode = "{mode}"\n' + body)
    return p


@pytest.fixture
def eight_gib(monkeypatch):
    """The checks as on a machine of 8 GiB (the test's numbers do not depend on this one)."""
    from spinweb_fe.sweep import limits

    monkeypatch.setattr(limits, "machine_memory", lambda: 8 * GIB)
    return 8 * GIB


def values(n, start=1.0):
    return "[" + ", ".join(f"{start + 0.001 * i:.4f}" for i in range(n)) + "]"


def test_a_grid_beyond_the_memory_is_refused_before_it_is_built(tmp_path, capsys, eight_gib):
    """50 x 50 x 30 = 75 000 runs: about 65 536 fit in a quarter of 8 GiB at 32 KB each. On
    main the grid was built and every run validated (a 1e6-run grid was accepted, a 1e9-run
    one ended in a MemoryError)."""
    body = (f'[grid]\n"hub.mass" = {values(50, 5.0)}\n"tip_mass.mass" = {values(50)}\n'
            f'"cable.damping_ratio" = {values(30, 0.0)}\n')
    path = sweep_file(tmp_path, body)
    assert main(["sweep", str(path), "--dry-run", "-o", str(tmp_path / "o")]) == 2
    line = one_line(capsys.readouterr().err)
    assert "75,000 runs" in line and "65,536" in line and "--force" in line, line


def test_the_run_limit_counts_members_and_yields_to_force():
    from spinweb_fe.errors import InputError
    from spinweb_fe.sweep.limits import RUN_BYTES, check_runs, count_runs

    assert count_runs(3, [1000, 1000, 1000], 0) == 3 * 10 ** 9  # no overflow, nothing built
    assert count_runs(2, [10], 100) == 2000
    memory = 1024 * RUN_BYTES * 4  # a quarter holds exactly 1024 runs
    check_runs(1024, "s.toml", memory=memory)
    with pytest.raises(InputError, match="1,025 runs"):
        check_runs(1025, "s.toml", memory=memory)
    check_runs(10 ** 9, "s.toml", force=True, memory=memory)


def test_too_many_workers_are_refused_and_force_starts_them(tmp_path, capsys, eight_gib):
    """--workers 10000 started 178 worker processes and 9 GB before it was stopped (main);
    now one line with the numbers, before any process starts (checked with --dry-run)."""
    path = sweep_file(tmp_path, '[grid]\n"hub.mass" = [5.0, 10.0]\n')
    argv = ["sweep", str(path), "--dry-run", "-o", str(tmp_path / "o")]
    assert main([*argv, "--workers", "10000"]) == 2
    line = one_line(capsys.readouterr().err)
    assert line.startswith("spinweb: error: --workers: 10000 worker processes of about ")
    assert "at most 28" in line and "--force" in line, line  # 0.8 * 8 GiB / 233 MB
    assert main([*argv, "--workers", "28"]) == 0
    assert main([*argv, "--workers", "10000", "--force"]) == 0
    capsys.readouterr()


@pytest.mark.parametrize("seed,ok", [(2 ** 63 - 1, True), (2 ** 63, False),
                                     (10 ** 30, False), (-1, False)])
def test_seeds_a_64_bit_integer_holds(tmp_path, capsys, seed, ok):
    """seed >= 2^63 crashed after every run had finished (summary.h5 stores it as int64)."""
    body = (f"members = 2\nseed = {seed}\n[random]\n"
            '"tip_mass.mass" = {dist = "uniform", low = 0.5, high = 1.5}\n')
    path = sweep_file(tmp_path, body, base="analytic_fig8_8pi.toml", mode="analytic")
    code = main(["sweep", str(path), "--dry-run", "-o", str(tmp_path / "o")])
    err = capsys.readouterr().err
    if ok:
        assert code == 0, err
    else:
        assert code == 2 and "seed: must be an integer from 0 to 2^63 - 1" in one_line(err)


def test_one_sweep_per_folder(tmp_path, capsys):
    """Two sweeps into one folder both ran (main), the second's runs finding the first's
    folders locked and the summary calling them failed; now the second is refused in one
    line, exit 1, before its cluster starts, and writes nothing."""
    from spinweb_fe.io.folder import SWEEP_LOCK, FolderLock

    path = sweep_file(tmp_path, '[grid]\n"hub.mass" = [5.0, 10.0]\n', base="analytic_fig8_8pi.toml",
                      mode="analytic")
    out = tmp_path / "o"
    with FolderLock(out, SWEEP_LOCK, "sweep"):  # the first sweep, still running
        assert main(["sweep", str(path), "-o", str(out), "--workers", "1"]) == 1
        line = one_line(capsys.readouterr().err)
    assert "is in use by another sweep" in line and "nothing was changed" in line, line
    assert not (out / "runs").exists() and not (out / "summary.csv").exists()


def test_a_design_folder_is_claimed_too(tmp_path, capsys):
    from spinweb_fe.io.folder import SWEEP_LOCK, FolderLock

    design = CASES / "design" / sorted(p.name for p in (CASES / "design").glob("*.toml"))[0]
    out = tmp_path / "d"
    with FolderLock(out, SWEEP_LOCK, "design"):
        assert main(["design", str(design), "-o", str(out), "--no-fe"]) == 1
        assert "is in use by another" in one_line(capsys.readouterr().err)
    assert not out.exists()  # the claim left no folder, the design wrote nothing
