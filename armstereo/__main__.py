import sys

from armstereo.cli.main import main

sys.exit(main())
