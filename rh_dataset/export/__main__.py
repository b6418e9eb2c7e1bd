"""`python -m rh_dataset.export` = `rh-export`."""
import sys

from .cli import main

sys.exit(main())
