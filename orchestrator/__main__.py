"""``python -m orchestrator``: the rotorcosim command line."""

from orchestrator.cli import console_main

if __name__ == "__main__":
    console_main()
