"""Every relative link in the repository's Markdown pages resolves: the file exists inside the
repository, and an anchor names a heading of the page it points to (GitHub's heading ids)."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")
FENCE = re.compile(r"^```.*?^```", re.S | re.M)
SKIP = {".git", ".venv", ".cache", "outputs", "node_modules", ".pytest_cache"}


def pages() -> list[Path]:
    return sorted(p for p in ROOT.rglob("*.md")
                  if not SKIP & set(p.relative_to(ROOT).parts))


def anchors(page: Path) -> set[str]:
    """The ids GitHub gives the page's headings: lower case, punctuation but - and _ dropped,
    spaces as -, a repeated id numbered."""
    seen: dict[str, int] = {}
    out = set()
    for title in re.findall(r"^#{1,6} +(.+?) *#*$", FENCE.sub("", page.read_text()), re.M):
        slug = re.sub(r"[^\w\- ]", "", title.strip().lower()).replace(" ", "-")
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        out.add(slug if n == 0 else f"{slug}-{n}")
    return out


def broken_links(page: Path, root: Path = ROOT) -> list[str]:
    root, out = root.resolve(), []
    for target in LINK.findall(FENCE.sub("", page.read_text())):
        if re.match(r"[a-z]+:", target):          # http:, https:, mailto:
            continue
        path, _, anchor = target.partition("#")
        dest = (page.parent / path).resolve() if path else page
        if root not in (dest, *dest.parents):
            out.append(f"{target} (outside the repository)")
        elif not dest.exists():
            out.append(f"{target} (no such file)")
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            out.append(f"{target} (no heading #{anchor} in {dest.relative_to(root)})")
    return out


def test_every_relative_link_in_the_docs_resolves():
    assert len(pages()) >= 10
    bad = {str(p.relative_to(ROOT)): b for p in pages() if (b := broken_links(p))}
    assert not bad, bad


def test_the_checker_finds_a_broken_link_and_a_missing_anchor(tmp_path):
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs/other.md").write_text("# Other\n\n## Pose transfer\n")
    page = tmp_path / "docs/page.md"
    page.write_text("# Title\n\n## A section, with punctuation\n\n"
                    "[ok](#a-section-with-punctuation) [ok](other.md#pose-transfer) "
                    "[gone](missing.md) [no anchor](other.md#no-such-heading) [out](../../x.md)\n"
                    "```\n[in code](not-checked.md)\n```\n")
    assert broken_links(page, tmp_path) == [
        "missing.md (no such file)",
        "other.md#no-such-heading (no heading #no-such-heading in docs/other.md)",
        "../../x.md (outside the repository)"]
