"""`python -m deltagen ...`: the same command line as the `deltagen` script."""

import sys

from deltagen.cli import main

if __name__ == "__main__":
    sys.exit(main())
