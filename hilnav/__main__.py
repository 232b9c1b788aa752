import sys

from hilnav.cli import main

sys.exit(main())
