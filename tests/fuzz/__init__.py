"""Coverage-guided fuzz targets (atheris), run by `make fuzz`; not part of the pytest suite.

    python -m tests.fuzz.run [SECONDS]           # every target, SECONDS each (default 60)
    python -m tests.fuzz.targets capture CORPUS -max_total_time=60

Each target takes arbitrary bytes, drives one layer as an attacker would (a capture file, a TCP
segment sequence, a display filter, a key spec) and fails on any exception the layer does not own: damage
must become notes, refused input a MavscopeError with one line, and a refused key spec never contains
the key. Seed corpora come from the bundled captures (made by scripts/make_captures.py) and `seeds.py`.
"""
