"""The documentation site (docs/): it builds from the repository with warnings as
errors and loads nothing from the network; read in headless Chromium at 1280 px (tests/browser.py), no
code block or table is wider than its text column, a check that fails on one planted; its index
leads to the drone and robot users' page, its footer names the authors; its API and CLI references
cover what the package exports; every tutorial runs and asserts what its page claims; the data spec
is the shared one."""
import re
import subprocess
import sys
from pathlib import Path

import pytest
from browser import WIDTHS, chromium, wide_blocks

import simucal.api
from simucal.cli import main

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
TUTORIALS = sorted(p.stem for p in (DOCS / "tutorials").glob("*.py"))
# an asset the browser would fetch from elsewhere: a script, stylesheet, image or font by http(s)
REMOTE = re.compile(r"<(?:script|link|img|iframe|source)\b[^>]*\b(?:src|href)=[\"']?(?:https?:)?//|"
                    r"(?:url\(|@import\s)\s*[\"']?(?:https?:)?//", re.I)
LONG = "simucal calibrate SET -o cal.json " + " ".join(f"--effect acc.quadratic.{a}" for a in "xyzxyz")
# a page as Sphinx lays one out (a text column, div.body), in no stylesheet of the site's: a code block that
# fits, one a line too long scrolls sideways, a table too wide for the column, a long line that wraps
PLANTED = f"""<!DOCTYPE html><html><body><div class="body" style="width: 500px; padding: 0 30px">
<div class="highlight"><pre>simucal demo -o out</pre></div>
<div class="highlight"><pre style="overflow: auto">{LONG}
simucal validate cal.json set</pre></div>
<table><tr><td style="white-space: nowrap">{LONG}</td></tr></table>
<pre style="white-space: pre-wrap">{LONG}</pre>
</div></body></html>"""


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


@pytest.mark.slow
def test_a_code_block_or_table_wider_than_its_column_is_found(tmp_path):
    (tmp_path / "planted.html").write_text(PLANTED)
    with chromium() as driver:
        found = wide_blocks(driver, tmp_path / "planted.html", WIDTHS["desktop"])
    assert [f.split("'")[:2] for f in found] == [["the code block ", LONG[:60]], ["the table ", LONG[:60]]], found


@pytest.mark.slow
def test_no_code_block_or_table_is_wider_than_its_column_at_1280_px(site):
    pages = sorted(site.rglob("*.html"))
    with chromium() as driver:
        found = [f"{p.relative_to(site)}: {b}" for p in pages for b in wide_blocks(driver, p, WIDTHS["desktop"])]
    assert not found, f"{len(found)} blocks on {len({f.split(':')[0] for f in found})} of {len(pages)} pages:\n" \
                      + "\n".join(found)


def test_the_index_leads_to_the_drone_page_and_the_footer_names_its_authors(site):
    index = (site / "index.html").read_text()
    assert 'href="drones.html"' in index, "the index does not link the drone and robot users' page"
    footer = index[index.index('<div class="footer">'):]
    assert re.match(r'<div class="footer">\s*&#169;\d{4}, the simucal authors\.', footer), footer[:200]


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
