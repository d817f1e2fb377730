import sys

from gcs_voice.cli import main

sys.exit(main())
