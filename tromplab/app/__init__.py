"""``tromplab app``: a local web workbench on the library (docs/app.md).

A Starlette application (:mod:`~tromplab.app.server`) serves one static page and a small JSON
interface; the page drops a table, shows what kind it is (:mod:`~tromplab.app.kinds`), offers
the options of the matching command read off the command line's own parser
(:mod:`~tromplab.app.forms`), runs the command's library calls in a process of its own
(:mod:`~tromplab.app.jobs`) in the session's temporary folder (:mod:`~tromplab.app.sessions`),
and shows the result (:mod:`~tromplab.app.payload`; a circuit: :mod:`~tromplab.app.circuit_page`,
a trend: :mod:`~tromplab.app.trend_page`) with the files the command writes to download. It sits above the command line, whose parsers it reads; it needs the ``app`` extra
(``pip install "tromplab[app]"``): importing :mod:`tromplab.app.server` without it fails.
"""
