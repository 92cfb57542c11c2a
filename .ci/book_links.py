#!/usr/bin/env python3
"""Link check of the rendered book (issue 37): every relative link and #anchor resolves.

Run after `mdbook build book`. For every rendered chapter (book/book/**/*.html but
print.html, which repeats every chapter), every relative `href`/`src`:

* inside the rendered book: the file exists and, with a fragment, the page has that id;
* outside the book (a repository file such as `../../../robots/tb6612-2kg.toml`,
  written relative to the chapter's source): the file or directory exists in the
  repository. mdBook rewrites a relative `x.md` link to `x.html`, so for a repository
  path ending in .html the .md is accepted. A fragment on a repository .md file must be
  one of its headings' GitHub anchors.

Absolute URLs (http:, https:, mailto:) are not fetched. Exits 1 naming the page, the
link and what is wrong for every broken link. `--self-test` checks the checker on a
small book of its own with one good and three broken links.
"""

import html.parser
import os
import re
import sys
import tempfile
import urllib.parse


class Page(html.parser.HTMLParser):
    """The links and the ids of one HTML page."""

    def __init__(self):
        super().__init__()
        self.links = []
        self.ids = set()

    def handle_starttag(self, tag, attrs):
        for name, value in attrs:
            if value is None:
                continue
            if name in ("id", "name"):
                self.ids.add(value)
            if (name == "href" and tag in ("a", "link")) or (name == "src" and tag in ("img", "script")):
                self.links.append(value)


def parse(path):
    page = Page()
    with open(path, encoding="utf-8") as f:
        page.feed(f.read())
    return page


def github_anchors(md_path):
    """GitHub's heading anchors of a markdown file (lowercase, punctuation dropped, spaces to -)."""
    anchors = set()
    fence = False
    with open(md_path, encoding="utf-8") as f:
        for line in f:
            if line.startswith("```"):
                fence = not fence
            m = None if fence else re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
            if m:
                text = re.sub(r"`|\*|_(?=\W)|\[|\]\([^)]*\)", "", m.group(1)).lower()
                slug = re.sub(r"[^\w\- ]", "", text).replace(" ", "-")
                base, n = slug, 1
                while slug in anchors:
                    slug = f"{base}-{n}"
                    n += 1
                anchors.add(slug)
    return anchors


def check(repo, book_dir, out_dir):
    """Returns the list of broken links as strings."""
    src_dir = os.path.join(book_dir, "src")
    pages = {}
    for root, _dirs, files in os.walk(out_dir):
        for name in files:
            if name.endswith(".html"):
                pages[os.path.normpath(os.path.join(root, name))] = None
    errors = []
    checked = 0
    for page_path in sorted(pages):
        rel_page = os.path.relpath(page_path, out_dir)
        if rel_page in ("print.html", "toc.html") or rel_page.startswith("fonts" + os.sep):
            continue
        page = pages[page_path] or parse(page_path)
        pages[page_path] = page
        for link in page.links:
            parts = urllib.parse.urlsplit(link)
            if parts.scheme or parts.netloc or link.startswith("//"):
                continue
            checked += 1
            target_rel = urllib.parse.unquote(parts.path)
            fragment = urllib.parse.unquote(parts.fragment)
            where = f"{rel_page}: link {link!r}"
            if target_rel == "":
                target = page_path
            else:
                target = os.path.normpath(os.path.join(os.path.dirname(page_path), target_rel))
            inside = os.path.commonpath([os.path.abspath(target), os.path.abspath(out_dir)]) == os.path.abspath(out_dir)
            if inside and os.path.exists(target):
                if fragment and target.endswith(".html"):
                    tp = pages.get(target) or parse(target)
                    pages[target] = tp
                    if fragment not in tp.ids:
                        errors.append(f"{where}: no id {fragment!r} in {os.path.relpath(target, out_dir)}")
                continue
            # Not in the rendered book: a repository path, relative to the chapter's source.
            src_page_dir = os.path.join(src_dir, os.path.dirname(rel_page))
            repo_target = os.path.normpath(os.path.join(src_page_dir, target_rel))
            in_src = os.path.commonpath([os.path.abspath(repo_target), os.path.abspath(src_dir)]) == os.path.abspath(src_dir)
            if in_src:
                errors.append(f"{where}: {os.path.relpath(repo_target, repo)} is not a rendered chapter (missing from SUMMARY.md, or a typo)")
                continue
            candidates = [repo_target]
            if repo_target.endswith(".html"):
                candidates.insert(0, repo_target[: -len(".html")] + ".md")
            found = next((c for c in candidates if os.path.exists(c)), None)
            if found is None:
                errors.append(f"{where}: neither a rendered page nor a repository file ({os.path.relpath(repo_target, repo)} does not exist)")
            elif fragment and found.endswith(".md") and fragment not in github_anchors(found):
                errors.append(f"{where}: {os.path.relpath(found, repo)} has no heading with anchor {fragment!r}")
    return errors, checked


def self_test():
    with tempfile.TemporaryDirectory() as repo:
        book = os.path.join(repo, "book")
        out = os.path.join(book, "book")
        os.makedirs(os.path.join(out, "how-to"))
        os.makedirs(os.path.join(book, "src", "how-to"))
        with open(os.path.join(repo, "NOTES.md"), "w") as f:
            f.write("# Notes\n\n## Two words\n")
        with open(os.path.join(out, "index.html"), "w") as f:
            f.write('<h1 id="top">x</h1><a href="how-to/a.html#here">ok</a>')
        with open(os.path.join(out, "how-to", "a.html"), "w") as f:
            f.write(
                '<h2 id="here">a</h2><a href="../index.html#nowhere">bad id</a>'
                '<a href="../../../NOTES.html#two-words">repo ok</a>'
                '<a href="../../../NOTES.html#three">repo bad anchor</a>'
                '<a href="../../../missing.toml">missing</a><a href="https://example.org/x">ext</a>'
            )
        errors, checked = check(repo, book, out)
        assert checked == 5, checked
        assert len(errors) == 3, errors
        assert any("no id 'nowhere'" in e for e in errors), errors
        assert any("no heading with anchor 'three'" in e for e in errors), errors
        assert any("missing.toml does not exist" in e for e in errors), errors
    print("book_links self-test: ok")


def main():
    if sys.argv[1:] == ["--self-test"]:
        self_test()
        return 0
    repo = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    book = os.path.join(repo, "book")
    out = os.path.join(book, "book")
    if not os.path.isfile(os.path.join(out, "index.html")):
        print(f"book_links: {out}/index.html missing: run `mdbook build book` first", file=sys.stderr)
        return 1
    errors, checked = check(repo, book, out)
    for e in errors:
        print(f"broken link: {e}", file=sys.stderr)
    if errors:
        print(f"book_links: {len(errors)} broken of {checked} relative links", file=sys.stderr)
        return 1
    print(f"book_links: {checked} relative links resolve")
    return 0


if __name__ == "__main__":
    sys.exit(main())
