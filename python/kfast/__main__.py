import sys

from kfast.cli import main

sys.exit(main())
