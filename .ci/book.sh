#!/usr/bin/env bash
# CI step of the book (issue 37): build it with mdBook and check that every
# relative link and #anchor resolves (.ci/book_links.py over the rendered HTML,
# repository paths included). mdBook is not a Debian package: a pinned
# `cargo install`, trimmed to the HTML renderer (no serve/watch/search), skipped
# when that version is already installed.
set -euo pipefail
cd "$(dirname "$0")/.."

MDBOOK_VERSION=0.4.52
if ! mdbook --version 2>/dev/null | grep -qx "mdbook v$MDBOOK_VERSION"; then
    cargo install mdbook --locked --version "$MDBOOK_VERSION" --no-default-features --quiet
fi
python3 .ci/book_links.py --self-test
rm -rf book/book
mdbook build book
python3 .ci/book_links.py
python3 .ci/book_links.py --sources --compare
