"""Numbers and strings at the edges (issue #46, item 6): refused at load in one line, exit 2,
nothing written (each was a traceback on main, or for a title with a NUL a broken folder,
for one with a newline a stored case that --restart could not read)."""

from pathlib import Path

import pytest

from spinweb_fe.cli import main

CASES = Path(__file__).parent.parent / "cases"
DEMO = (CASES / "demo.toml").read_text()


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


EDGES = {  # name: (replace, by, key, words)
    "400_digit_side": ("side = 20.0", "side = 1" + "0" * 400, "web.side",
                       "an integer of 401 digits"),
    "400_digit_count": ("elements_per_segment = 1", "elements_per_segment = 1" + "0" * 400,
                        "web.elements_per_segment", "beyond the integers"),
    "5000_digit_int": ("elements_per_segment = 1", "elements_per_segment = 1" + "0" * 5000,
                       "", "an integer of more than 4300 digits"),
    "side_1e300": ("side = 20.0", "side = 1e300", "web.side", "cable elements"),
    "deep_1000": ('title = "', "x = " + "[" * 1000 + "]" * 1000 + '\ntitle = "', "",
                  "nested too deep"),
    "deep_20": ('title = "', "x = " + "[" * 20 + "]" * 20 + '\ntitle = "', "",
                "nested 21 levels deep"),
    "nul_title": ('title = "demo', 'title = "de\\u0000mo', "title", "'\\x00'"),
    "newline_title": ('title = "demo', 'title = "de\\nmo', "title", "'\\n'"),
    "escape_title": ('title = "demo', 'title = "\\u001b[31mred', "title", "'\\x1b'"),
    "long_title": ('title = "demo', 'title = "' + "x" * 5000, "title",
                   "5051 characters long (at most 4096)"),
}


@pytest.mark.parametrize("name", sorted(EDGES))
def test_an_edge_is_one_line_at_load(name, tmp_path, capsys):
    old, new, key, words = EDGES[name]
    case = tmp_path / f"{name}.toml"
    assert old in DEMO
    case.write_text(DEMO.replace(old, new, 1))
    out = tmp_path / "out"
    for argv in (["check", str(case)], ["run", str(case), "-o", str(out)]):
        assert main(argv) == 2
        line = one_line(capsys.readouterr().err)
        assert line.startswith(f"spinweb: error: {case}: {key + ': ' if key else ''}"), line
        assert words in line, line
    assert not out.exists()


@pytest.mark.parametrize("value,words", [("1" + "0" * 5000, "4300 digits"),
                                         ("[" * 30 + "]" * 30, "nested more than 16")])
def test_an_edge_in_a_set_is_one_line(value, words, capsys):
    assert main(["check", str(CASES / "demo.toml"), "--set", f"web.side={value}"]) == 2
    line = one_line(capsys.readouterr().err)
    assert line.startswith("spinweb: error: --set: web.side: ") and words in line, line


@pytest.mark.parametrize("body,words", [
    ('seed = 1' + '0' * 5000 + '\n', "4300 digits"),
    ('x = ' + '[' * 1000 + ']' * 1000 + '\n', "nested too deep"),
    ('[grid]\n"web.side" = [1' + '0' * 400 + ']\n', "an integer of 401 digits"),
])
def test_sweep_files_at_the_edges(tmp_path, capsys, body, words):
    sweep = tmp_path / "s.toml"
    sweep.write_text(f'base = "{CASES / "demo.toml"}"\n' + body)
    assert main(["sweep", str(sweep), "--dry-run", "-o", str(tmp_path / "o")]) == 2
    assert words in one_line(capsys.readouterr().err)


def test_the_stored_case_reads_back_with_any_text():
    """dumps_toml escapes control characters: a stored case (results.h5, a checkpoint) is
    TOML again whatever a string holds (on main a newline broke --restart)."""
    import tomllib

    from spinweb_fe.case.text import dumps_toml

    d = {"title": "a\nb\x00c\"d\\e\x7f", "web": {"side": 1.0}}
    assert tomllib.loads(dumps_toml(d)) == d
