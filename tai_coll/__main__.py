"""`python -m tai_coll ...`: the same commands as `tai-coll ...`."""

import sys

from .cli import main

sys.exit(main())
