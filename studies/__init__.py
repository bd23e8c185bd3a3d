"""psns-hil studies: dated investigations (``studies/*.md``) and the scripts that made their numbers
(``studies.scripts``).

Not part of the installed package and not a benchmark: ``make bench`` runs ``benchmarks/``; a study script is run by
hand, ``python -m studies.scripts.NAME``, and its output is quoted in the study that used it.
"""
