"""Check that the built documentation site loads nothing from another host: no ``<script src>``,
stylesheet, font or image from ``http(s)://`` or ``//`` on any page (the site reads offline, and a
page of ours never runs someone else's code).  Links to other sites (``<a href>``) are fine.

Usage: ``python .ci/check_offline_site.py [docs/_build/html]``; exit 1 listing every remote load.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

#: A tag that loads what its attribute names: scripts, stylesheets and icons, images, frames.
LOADS = re.compile(
    r"<(?:script|img|iframe|source|embed)\b[^>]*?\bsrc\s*=\s*[\"']?(?P<src>[^\"'\s>]+)"
    r"|<link\b(?=[^>]*\brel\s*=\s*[\"']?(?:stylesheet|preload|modulepreload|icon|shortcut icon)\b)[^>]*?\bhref\s*=\s*[\"']?(?P<href>[^\"'\s>]+)"
    r"|@import\s+(?:url\()?[\"']?(?P<import>[^\"')\s;]+)",
    re.IGNORECASE,
)
REMOTE = re.compile(r"^(?:[a-z][a-z0-9+.-]*:)?//", re.IGNORECASE)


def remote_loads(html: str) -> list[str]:
    """The addresses ``html`` loads from another host.

    >>> remote_loads('<script src="https://code.jquery.com/jquery-3.7.0.js"></script><script src="_static/a.js"></script>')
    ['https://code.jquery.com/jquery-3.7.0.js']
    >>> remote_loads('<a href="https://example.org">a link</a><link rel="stylesheet" href="//cdn.x/y.css">')
    ['//cdn.x/y.css']
    """
    found = []
    for match in LOADS.finditer(html):
        address = next(value for value in match.groups() if value)
        if REMOTE.match(address) and not address.lower().startswith("data:"):
            found.append(address)
    return found


def main(folder: str = "docs/_build/html") -> int:
    pages = sorted(Path(folder).rglob("*.html"))
    if not pages:
        print(f"{folder}: no HTML page (build the site first)", file=sys.stderr)
        return 1
    bad = {page: remote_loads(page.read_text(encoding="utf-8", errors="replace")) for page in pages}
    bad = {page: found for page, found in bad.items() if found}
    for page, found in bad.items():
        print(f"{page}: loads {', '.join(sorted(set(found)))}", file=sys.stderr)
    if bad:
        return 1
    print(f"{len(pages)} pages, none loads anything from another host")
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
