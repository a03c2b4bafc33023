"""The documentation site (docs/): it builds from the repository with warnings as
errors and loads nothing from the network; its API and CLI references cover what the package
exports; every tutorial runs and asserts what its page claims; the data spec is the shared one."""
import re
import subprocess
import sys
from pathlib import Path

import pytest

import simucal.api
from simucal.cli import main

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
TUTORIALS = sorted(p.stem for p in (DOCS / "tutorials").glob("*.py"))
# an asset the browser would fetch from elsewhere: a script, stylesheet, image or font by http(s)
REMOTE = re.compile(r"<(?:script|link|img|iframe|source)\b[^>]*\b(?:src|href)=[\"']?(?:https?:)?//|"
                    r"(?:url\(|@import\s)\s*[\"']?(?:https?:)?//", re.I)


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """The site built as CI builds it: sphinx-build -W into a folder of its own (docs/ is not written)."""
    out = tmp_path_factory.mktemp("site")
    r = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", str(DOCS),
                        str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    return out


@pytest.mark.slow
def test_the_site_builds_with_warnings_as_errors_and_opens_offline(site):
    pages = [p for p in site.rglob("*") if p.suffix in (".html", ".css", ".js")]
    assert len([p for p in pages if p.suffix == ".html"]) >= 10
    remote = {str(p.relative_to(site)): REMOTE.search(p.read_text(errors="replace")).group(0)
              for p in pages if REMOTE.search(p.read_text(errors="replace"))}
    assert not remote, remote


def test_the_references_cover_every_api_name_and_every_command(site):
    api, cli = (site / "api.html").read_text(), (site / "cli.html").read_text()
    missing = [n for n in simucal.api.__all__ if f'id="simucal.api.{n}"' not in api]
    assert not missing, f"the API reference lacks {missing}"
    missing = [c for c in main.commands if f'id="simucal-{c}"' not in cli]
    assert not missing, f"the CLI reference lacks {missing}"


def test_the_spec_page_is_the_shared_spec_and_its_extensions():
    """The data format lives in shared/spec/ beside the repository, a contract simucal may only
    extend compatibly. docs/ carries it unchanged (cp ../shared/spec/measurement-set.md docs/spec/)
    followed by one section of simucal's additions, so the contract itself is never edited here."""
    shared = (ROOT.parent / "shared" / "spec" / "measurement-set.md").read_text()
    page = (DOCS / "spec" / "measurement-set.md").read_text()
    assert page.startswith(shared), "docs/spec/ no longer begins with the shared spec, unchanged"
    extensions = page[len(shared):]
    assert extensions.startswith("\n## simucal's compatible extensions\n")
    assert extensions.count("\n## ") == 1, "the additions are one section, after the contract"


def test_every_tutorial_has_its_page_in_the_index():
    index = (DOCS / "tutorials" / "index.md").read_text()
    assert len(TUTORIALS) >= 5
    for name in TUTORIALS:
        assert re.search(rf"^{name}$", index, re.M), f"tutorials/index.md does not list {name}"
        assert f"```{{literalinclude}} {name}.py" in (DOCS / "tutorials" / f"{name}.md").read_text()


@pytest.mark.slow
@pytest.mark.parametrize("name", TUTORIALS)
def test_the_tutorial_runs_and_its_claims_hold(tmp_path, name):
    """Each script asserts its page's claims; run as a reader would, in an empty folder."""
    r = subprocess.run([sys.executable, str(DOCS / "tutorials" / f"{name}.py")], cwd=tmp_path,
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.strip(), "a tutorial shows what it found"
