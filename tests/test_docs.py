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
