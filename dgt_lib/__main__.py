import sys

from dgt_lib.cli import main

sys.exit(main())
