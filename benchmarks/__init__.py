"""psns-hil benchmarks: ``python -m benchmarks`` (``make bench``)."""
