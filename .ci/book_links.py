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

The repository's entry pages (README.md, firmware/README.md, docs/DECISIONS.md) are
checked too: their relative links exist, their anchors name a heading.
Absolute URLs (http:, https:, mailto:) are not fetched. Exits 1 naming the page, the
link and what is wrong for every broken link. `--self-test` checks the checker on a
small book of its own with good and broken links, in both modes.

`--sources`: the same check on the markdown sources without mdBook (chapters from
SUMMARY.md, mdBook's heading-id rule); `--sources --compare` also checks that rule
against the rendered book (every chapter's heading ids equal).
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
        self.heading_ids = []

    def handle_starttag(self, tag, attrs):
        for name, value in attrs:
            if value is None:
                continue
            if name in ("id", "name"):
                self.ids.add(value)
                if re.fullmatch(r"h[1-6]", tag) and name == "id":
                    self.heading_ids.append(value)
            if (name == "href" and tag in ("a", "link")) or (name == "src" and tag in ("img", "script")):
                self.links.append(value)


def relative(link):
    """A relative link's (path, fragment), unquoted; None for an external one."""
    parts = urllib.parse.urlsplit(link)
    if parts.scheme or parts.netloc or link.startswith("//"):
        return None
    return urllib.parse.unquote(parts.path), urllib.parse.unquote(parts.fragment)


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
            rel = relative(link)
            if rel is None:
                continue
            checked += 1
            target_rel, fragment = rel
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


# ---- Source mode: the same check on the markdown sources, without mdBook ----
# (the cheap alternative when mdBook is not installed: see D180). Chapters are the
# links of SUMMARY.md outside HTML comments; {{#include}} is expanded; a heading's id
# is its explicit {#id} or mdBook's rule (id_from_content: tags and markdown markup
# dropped, alphanumerics, '_' and '-' kept and ASCII-lowercased, whitespace to '-',
# the rest dropped; a repeated id gets -1, -2, ...). `--sources --compare` checks this
# rule against a rendered book: every page's heading ids equal.

def mdbook_id(text):
    # A code span's `<kind>` is text, not a tag (mdBook drops its &lt;/&gt;).
    text = re.sub(r"`([^`]*)`", lambda m: m.group(1).replace("<", "").replace(">", ""), text)
    text = re.sub(r"<[^>]*>", "", text)
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", text)
    text = text.replace("`", "").replace("*", "")
    text = text.replace("&amp;", "&").replace("&lt;", "<").replace("&gt;", ">").replace("&quot;", '"').replace("&#39;", "'")
    out = []
    for ch in text.strip():
        if ch.isalnum() or ch in "_-":
            out.append(ch.lower() if ch.isascii() else ch)
        elif ch.isspace():
            out.append("-")
    return "".join(out)


def strip_comments(text):
    return re.sub(r"<!--.*?-->", "", text, flags=re.S)


def expand_includes(text, base_dir):
    def inc(m):
        with open(os.path.normpath(os.path.join(base_dir, m.group(1).strip())), encoding="utf-8") as f:
            return f.read()
    return re.sub(r"\{\{#include ([^}]+)\}\}", inc, text)


def source_chapters(src_dir):
    with open(os.path.join(src_dir, "SUMMARY.md"), encoding="utf-8") as f:
        summary = strip_comments(f.read())
    return [m.group(1) for m in re.finditer(r"\]\(([^)#]+\.md)\)", summary)]


def source_page(path):
    """(links, heading ids) of one chapter's markdown, code blocks and spans left out."""
    with open(path, encoding="utf-8") as f:
        text = expand_includes(f.read(), os.path.dirname(path))
    links, ids, seen = [], [], {}
    fence = False
    for line in text.split("\n"):
        if re.match(r"^\s*(```|~~~)", line):
            fence = not fence
            continue
        if fence:
            continue
        m = re.match(r"^#{1,6}\s+(.*?)\s*$", line)
        if m:
            head = m.group(1)
            explicit = re.search(r"\s*\{#([^}\s]+)\}\s*$", head)
            if explicit:
                ident = explicit.group(1)
            else:
                ident = mdbook_id(head)
                if ident in seen:
                    seen[ident] += 1
                    ident = f"{ident}-{seen[ident]}"
                else:
                    seen[ident] = 0
            ids.append(ident)
        line = re.sub(r"`[^`]*`", "", line)
        links += re.findall(r"\]\(([^)\s]+)\)", line)
        links += re.findall(r"<a\s[^>]*href=\"([^\"]+)\"", line)
        ids += re.findall(r"<a\s[^>]*(?:id|name)=\"([^\"]+)\"", line)
    return links, ids


def check_sources(repo, book_dir):
    src_dir = os.path.join(book_dir, "src")
    chapters = source_chapters(src_dir)
    errors, checked = [], 0
    pages = {}
    for ch in chapters:
        path = os.path.normpath(os.path.join(src_dir, ch))
        if not os.path.isfile(path):
            errors.append(f"SUMMARY.md: chapter {ch} does not exist")
            continue
        pages[path] = source_page(path)
    for path, (links, _ids) in sorted(pages.items()):
        rel_page = os.path.relpath(path, src_dir)
        for link in links:
            rel = relative(link)
            if rel is None:
                continue
            checked += 1
            target_rel, fragment = rel
            where = f"{rel_page}: link {link!r}"
            target = path if target_rel == "" else os.path.normpath(os.path.join(os.path.dirname(path), target_rel))
            in_src = os.path.commonpath([os.path.abspath(target), os.path.abspath(src_dir)]) == os.path.abspath(src_dir)
            if in_src and target.endswith(".md"):
                if target not in pages:
                    errors.append(f"{where}: {os.path.relpath(target, repo)} is not a chapter of SUMMARY.md")
                elif fragment and fragment not in pages[target][1]:
                    errors.append(f"{where}: no heading with id {fragment!r} in {os.path.relpath(target, src_dir)}")
            elif not os.path.exists(target):
                errors.append(f"{where}: {os.path.relpath(target, repo)} does not exist")
            elif fragment and target.endswith(".md") and fragment not in github_anchors(target):
                errors.append(f"{where}: {os.path.relpath(target, repo)} has no heading with anchor {fragment!r}")
    return errors, checked, pages


# Repository pages that point into the book: their relative links are checked too.
ENTRY_PAGES = ["README.md", "firmware/README.md", "docs/DECISIONS.md"]


def check_entry_pages(repo, book_dir, pages):
    """Links of the repository's entry pages: the file exists; an anchor on a chapter is
    one of its heading ids, on another markdown file one of its GitHub anchors."""
    errors, checked = [], 0
    for name in ENTRY_PAGES:
        path = os.path.join(repo, name)
        if not os.path.isfile(path):
            continue
        links, _ids = source_page(path)
        for link in links:
            parts = urllib.parse.urlsplit(link)
            if parts.scheme or parts.netloc or link.startswith("//"):
                continue
            checked += 1
            target_rel = urllib.parse.unquote(parts.path)
            fragment = urllib.parse.unquote(parts.fragment)
            target = path if target_rel == "" else os.path.normpath(os.path.join(os.path.dirname(path), target_rel))
            where = f"{name}: link {link!r}"
            if not os.path.exists(target):
                errors.append(f"{where}: {os.path.relpath(target, repo)} does not exist")
            elif fragment and target in pages and fragment not in pages[target][1]:
                errors.append(f"{where}: no heading with id {fragment!r} in {os.path.relpath(target, repo)}")
            elif fragment and target not in pages and target.endswith(".md") and fragment not in github_anchors(target):
                errors.append(f"{where}: {os.path.relpath(target, repo)} has no heading with anchor {fragment!r}")
    return errors, checked


def compare_ids(book_dir, out_dir, pages):
    """The source mode's heading ids against the rendered pages' (the rule's check)."""
    src_dir = os.path.join(book_dir, "src")
    diffs = []
    for path, (_links, ids) in sorted(pages.items()):
        rel = os.path.relpath(path, src_dir)
        html_path = os.path.join(out_dir, rel[: -len(".md")] + ".html")
        if os.path.basename(rel) == "README.md":
            html_path = os.path.join(out_dir, os.path.dirname(rel), "index.html")
        rendered = parse(html_path)
        heads = set(rendered.heading_ids)
        if set(ids) - rendered.ids or heads - set(ids):
            diffs.append(f"{rel}: only in the sources {sorted(set(ids) - rendered.ids)[:5]}, only rendered {sorted(heads - set(ids))[:5]}")
    return diffs


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
        src = os.path.join(book, "src")
        with open(os.path.join(src, "SUMMARY.md"), "w") as f:
            f.write("# Summary\n\n- [A](how-to/a.md)\n<!-- pending: - [B](how-to/b.md) -->\n")
        with open(os.path.join(src, "how-to", "a.md"), "w") as f:
            f.write(
                "# Run `wmr serve` twice\n\n## D1. One {#d1}\n\n[ok](#run-wmr-serve-twice) [ok](#d1) "
                "[bad](#d2) [repo](../../../NOTES.md#two-words) [pending](b.md)\n\n```\n[code](nowhere.md)\n```\n"
            )
        errors, checked, _pages = check_sources(repo, book)
        assert checked == 5, checked
        assert len(errors) == 2, errors
        assert any("no heading with id 'd2'" in e for e in errors), errors
        assert any("b.md is not a chapter" in e for e in errors), errors
    print("book_links self-test: ok")


def main():
    if sys.argv[1:] == ["--self-test"]:
        self_test()
        return 0
    repo = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    book = os.path.join(repo, "book")
    out = os.path.join(book, "book")
    if sys.argv[1:2] == ["--sources"]:
        errors, checked, pages = check_sources(repo, book)
        more, n = check_entry_pages(repo, book, pages)
        errors, checked = errors + more, checked + n
        if sys.argv[2:] == ["--compare"]:
            errors += [f"heading ids differ from mdBook's: {d}" for d in compare_ids(book, out, pages)]
        for e in errors:
            print(f"broken link: {e}", file=sys.stderr)
        if errors:
            print(f"book_links --sources: {len(errors)} problems, {checked} relative links", file=sys.stderr)
            return 1
        print(f"book_links --sources: {checked} relative links of {len(pages)} chapters resolve")
        return 0
    if not os.path.isfile(os.path.join(out, "index.html")):
        print(f"book_links: {out}/index.html missing: run `mdbook build book` first", file=sys.stderr)
        return 1
    errors, checked = check(repo, book, out)
    _errors, _checked, pages = check_sources(repo, book)
    more, n = check_entry_pages(repo, book, pages)
    errors, checked = errors + more, checked + n
    for e in errors:
        print(f"broken link: {e}", file=sys.stderr)
    if errors:
        print(f"book_links: {len(errors)} broken of {checked} relative links", file=sys.stderr)
        return 1
    print(f"book_links: {checked} relative links resolve")
    return 0


if __name__ == "__main__":
    sys.exit(main())
