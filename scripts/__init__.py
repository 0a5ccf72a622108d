"""Makes scripts/ a package so that the tests can import the capture generator's independent frame
encoder as `scripts.capgen.encode` with a plain import: the tests already import from the repository
root (`tests.conftest`), which is on sys.path under pytest, so no path manipulation is needed.
`python scripts/make_captures.py` still runs as a script (it imports `capgen` from beside itself)."""
