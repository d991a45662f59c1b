import sys

from spinweb_fe.cli import main

sys.exit(main())
