"""The documentation: a short README that reaches every page of the site, and benchmark
tables that are the benchmarks' own output, not edited by hand."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from fleet.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
GENERATED = re.compile(
    r"<!-- generated: (?P<json>[\w.-]+\.json) -->\n(?P<table>.*?)\n<!-- end generated -->",
    re.DOTALL,
)


def test_the_readme_is_short_and_links_every_page_of_the_site() -> None:
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 250
    linked = set(re.findall(r"\]\(docs/([\w-]+\.md)\)", readme))
    pages = {p.name for p in DOCS.glob("*.md")} - {"index.md"}
    assert pages <= linked, f"pages the README does not link: {sorted(pages - linked)}"
    assert all((DOCS / page).is_file() for page in linked), "a README link to no page"
    nav = (ROOT / "mkdocs.yml").read_text()
    assert all(page in nav for page in pages | {"index.md"}), "a page missing from the nav"


def test_benchmark_tables_are_the_benchmarks_own_markdown(
    capsys: pytest.CaptureFixture[str],
) -> None:
    blocks = [(page, m) for page in DOCS.glob("*.md") for m in GENERATED.finditer(page.read_text())]
    assert blocks, "no generated benchmark table in the docs"
    for page, block in blocks:
        results = DOCS / "results" / block["json"]
        assert main(["bench", "fleet", "--from-json", str(results), "--markdown"]) == 0
        printed = capsys.readouterr().out.strip()
        assert block["table"].strip() == printed, (
            f"{page.name}: the table from {results.name} was edited by hand or is stale; "
            f"paste `parkfleet bench fleet --from-json docs/results/{results.name} --markdown`"
        )
