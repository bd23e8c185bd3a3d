"""``python -m emulator`` is ``psns-hil``."""

import sys

from .cli import main

sys.exit(main())
