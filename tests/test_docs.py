"""The documentation site: it builds with warnings as errors, its commands exist with their options,
the README's links reach its pages, and no page carries the project's history (that is CHANGELOG.md)."""

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from test_readme import README, check_command, fenced_blocks, shell_commands

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted(DOCS.rglob("*.md"))
HAVE_MKDOCS = all(importlib.util.find_spec(m) is not None for m in ("mkdocs", "material", "mkdocstrings_handlers"))

# journal words, not documentation: a stop or issue number, a case number of a seeded matrix
JOURNAL = re.compile(r"stop [0-9]+|issue #?[0-9]+|[0-9]{4} #[0-9]+|seed [0-9]{4} |fixed #[0-9]+", re.I)


def test_docs_have_the_pages_of_every_area():
    names = {p.name for p in PAGES}
    for page in (
        "index.md",
        "simulator.md",
        "environments.md",
        "controllers.md",
        "agents.md",
        "model_vs_measurement.md",
        "hardware.md",
        "scale_out.md",
        "benchmarks.md",
        "EFFECTS.md",
        "CORE_API.md",
        "bifurcation_verification.md",
        "changelog.md",
    ):
        assert page in names, f"docs/{page} is missing"


@pytest.mark.parametrize("path", [ROOT / "README.md", ROOT / "CHANGELOG.md", *PAGES], ids=lambda p: p.name)
def test_no_journal_words(path):
    text = path.read_text(encoding="utf-8")
    hits = [m.group(0) for m in JOURNAL.finditer(text)]
    assert not hits, f"{path.relative_to(ROOT)}: journal words {hits[:5]} (history goes to CHANGELOG.md)"


def test_readme_is_a_front_door():
    assert len(README.splitlines()) <= 300


def test_readme_links_reach_files():
    for target in re.findall(r"\]\(((?:docs/|CHANGELOG)[^)#]+)", README):
        assert (ROOT / target).exists(), f"README links to {target}, which does not exist"


@pytest.mark.parametrize("path", PAGES, ids=lambda p: str(p.relative_to(DOCS)))
def test_page_commands_exist_with_their_options(path):
    text = path.read_text(encoding="utf-8")
    for cmd in shell_commands(text):
        check_command(cmd, f"docs/{path.relative_to(DOCS)}")
    # every benchmark command the page gives: the script exists and takes the options shown
    for _lang, body in fenced_blocks(text) + [("", m) for m in re.findall(r"`([^`]*benchmarks/\w+\.py[^`]*)`", text)]:
        for line in body.replace("\\\n", " ").splitlines():
            m = re.search(r"(benchmarks/\w+\.py)(.*)", line.split("#")[0])
            if not m or "python" not in line:
                continue
            script = ROOT / m.group(1)
            assert script.exists(), f"docs/{path.relative_to(DOCS)}: {m.group(1)} does not exist"
            source = script.read_text(encoding="utf-8")
            for opt in re.findall(r"(--[a-z][a-z0-9-]*)", m.group(2)):
                assert f'"{opt}"' in source, f"docs/{path.relative_to(DOCS)}: {m.group(1)} has no option {opt}"


def test_mkdocs_nav_names_existing_pages():
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    for page in re.findall(r":\s*([\w/.-]+\.md)\s*$", nav, flags=re.M):
        assert (DOCS / page).exists(), f"mkdocs.yml names docs/{page}, which does not exist"


@pytest.mark.slow
@pytest.mark.skipif(
    not HAVE_MKDOCS,
    reason="mkdocs-material and mkdocstrings[python] are not installed "
    "(pip install -e '.[docs]'; make venv installs them)",
)
def test_docs_site_builds_with_warnings_as_errors(tmp_path):
    res = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )
    assert res.returncode == 0, res.stderr[-4000:]
    assert (tmp_path / "site" / "index.html").exists()
    assert (tmp_path / "site" / "api" / "simulation" / "index.html").exists()
    # numpydoc's cross-reference roles are rendered (docs/griffe_sphinx_roles.py), never shown raw
    for page in (tmp_path / "site" / "api").rglob("index.html"):
        raw = re.findall(r":(?:class|func|meth|mod|attr|exc):`", page.read_text(encoding="utf-8"))
        assert not raw, f"{page.relative_to(tmp_path)} shows {len(raw)} Sphinx roles as text"


def test_make_docs_target_builds_strict():
    make = (ROOT / "Makefile").read_text(encoding="utf-8")
    target = re.search(r"^docs:.*\n((?:\t.*\n)+)", make, flags=re.M)
    assert target, "the Makefile has no docs target"
    assert "mkdocs build --strict" in target.group(1)


# --- the product stands on its own: no file outside the repository, the model page follows the code

#: a file outside the repository that a clone does not have (the model and the time-series format are
#: docs/model.md and docs/data_format.md); written so that this file does not match itself
OUTSIDE = re.compile(r"\.\./shared\b|\bshared[/\\](?:MODEL|DATA_FORMAT)\.md")
#: files allowed to name them: the history
OUTSIDE_ALLOWED = {"CHANGELOG.md"}


def outside_references(root: Path, names: list[str]) -> list[str]:
    """``file:line: text`` of every line of the named text files (relative to ``root``) that sends the reader
    to a file outside the repository; binary files are skipped."""
    hits = []
    for name in names:
        if name in OUTSIDE_ALLOWED:
            continue
        try:
            text = (root / name).read_text(encoding="utf-8")
        except (UnicodeDecodeError, IsADirectoryError, FileNotFoundError):
            continue
        for lineno, line in enumerate(text.splitlines(), start=1):
            if OUTSIDE.search(line):
                hits.append(f"{name}:{lineno}: {line.strip()[:100]}")
    return hits


def tracked_files() -> list[str]:
    """The repository's tracked files (``git ls-files``), paths relative to its root."""
    try:
        res = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        pytest.skip("git is not available")
    if res.returncode != 0:
        pytest.skip("not a git checkout")
    return [n for n in res.stdout.decode("utf-8").split("\0") if n]


def test_no_tracked_file_sends_the_reader_outside_the_repository():
    hits = outside_references(ROOT, tracked_files())
    assert not hits, (
        "files outside the repository are named (the model is docs/model.md, the time-series format "
        "docs/data_format.md):\n" + "\n".join(hits[:20])
    )


def test_outside_references_are_found(tmp_path):
    """The check above can fail: each form is found, in any file but the changelog."""
    (tmp_path / "a.py").write_text(
        '"""Parameters of\n' + "/".join(("..", "shared", "MODEL.md")) + '."""\n', encoding="utf-8"
    )
    (tmp_path / "b.md").write_text("see `" + "/".join(("shared", "DATA_FORMAT.md")) + "`\n", encoding="utf-8")
    (tmp_path / "c.txt").write_text("the model page is docs/model.md\n", encoding="utf-8")
    (tmp_path / "CHANGELOG.md").write_text(
        "- moved from " + "/".join(("..", "shared", "MODEL.md")) + "\n", encoding="utf-8"
    )
    (tmp_path / "d.bin").write_bytes(b"\xff\xfe\x00")
    hits = outside_references(tmp_path, ["a.py", "b.md", "c.txt", "CHANGELOG.md", "d.bin"])
    assert [h.split(":")[0] for h in hits] == ["a.py", "b.md"]
    assert hits[0].startswith("a.py:2: ")


def parameter_rows(page: str) -> dict[str, dict[str, str]]:
    """The parameter table of the model page's "Parameters" section: code name -> {column: cell}."""
    m = re.search(r"^## Parameters\n(.*?)(?=^##)", page, flags=re.M | re.S)
    assert m, 'docs/model.md has no "## Parameters" section'
    header: list[str] | None = None
    rows: dict[str, dict[str, str]] = {}
    for line in m.group(1).splitlines():
        if not line.startswith("|"):
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if header is None:
            header = cells
        elif not set("".join(cells)) <= set("-: "):
            rows[cells[0].strip("`")] = dict(zip(header, cells))
    return rows


def parameter_drift(page: str) -> list[str]:
    """Where the model page's parameter table differs from ``RigParams``: a parameter missing or extra, or
    a default value, unit or source that is not the code's."""
    from drillgym.params import PARAM_INFO, RigParams

    rows = parameter_rows(page)
    problems = [f"{name}: on the page, not in RigParams" for name in rows if name not in PARAM_INFO]
    for name, value in RigParams().to_dict().items():
        row = rows.get(name)
        if row is None:
            problems.append(f"{name}: no row in the parameter table")
            continue
        try:
            shown = float(row.get("value", "").replace("−", "-"))
        except ValueError:
            shown = None
        if shown != value:
            problems.append(f"{name}: the page says {row.get('value')!r}, the default is {value!r}")
        unit = row.get("unit", "").replace("²", "^2")
        if unit != PARAM_INFO[name]["unit"]:
            problems.append(f"{name}: unit {row.get('unit')!r} on the page, {PARAM_INFO[name]['unit']!r} in the code")
        if not row.get("source", "").startswith(PARAM_INFO[name]["source"]):
            problems.append(f"{name}: source {row.get('source')!r}, the code says {PARAM_INFO[name]['source']!r}")
    return problems


def test_model_page_gives_every_parameter_with_its_default():
    page = (DOCS / "model.md").read_text(encoding="utf-8")
    problems = parameter_drift(page)
    assert not problems, "docs/model.md and drillgym.params.RigParams disagree:\n" + "\n".join(problems)


def test_parameter_drift_is_found():
    """The check above can fail: a changed value, a wrong unit, a missing row and an unknown row."""
    page = (DOCS / "model.md").read_text(encoding="utf-8")
    assert not parameter_drift(page)
    changed = page.replace("| 0.2781 | N m |", "| 0.2782 | N m |").replace("| 2974.25 | N/m |", "| 2974.25 | N |")
    problems = parameter_drift(changed)
    assert any(p.startswith("Ts: the page says '0.2782'") for p in problems), problems
    assert any(p.startswith("k: unit 'N'") for p in problems), problems
    lines = [ln for ln in page.splitlines() if not ln.startswith("| `bb` |")]
    lines.insert(lines.index(next(ln for ln in lines if ln.startswith("| `e` |"))), "| `Tx` | Tx | - | 1 | N m | - |")
    problems = parameter_drift("\n".join(lines) + "\n")
    assert "bb: no row in the parameter table" in problems
    assert "Tx: on the page, not in RigParams" in problems
