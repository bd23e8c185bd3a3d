"""The study and profiling scripts: each is run as ``python -m studies.scripts.NAME`` from the repository root
(studies/README.md lists which study each one served)."""
