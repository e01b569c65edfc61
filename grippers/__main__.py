import sys

from grippers.cli import main

sys.exit(main())
