import sys

from dgt_lib.app.cli import main

sys.exit(main())
