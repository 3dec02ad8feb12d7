import sys

from dombot_ros2.cli import main

sys.exit(main())
