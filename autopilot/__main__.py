import sys

try:
    from autopilot.cli import main
except KeyboardInterrupt:  # a Ctrl-C while Python loads the command
    sys.stderr.write("autopilot: interrupted\n")
    sys.exit(130)

sys.exit(main())
