"""`python -m wearnav` is the `wearnav` command."""

from wearnav.cli import main

if __name__ == "__main__":
    main()
