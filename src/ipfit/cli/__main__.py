import sys

try:
    from . import main
except KeyboardInterrupt:  # Ctrl-C while Python is still importing: nothing started, nothing to say
    sys.exit(130)

sys.exit(main())
