"""``python -m busarm``: the busarm command line."""

from busarm.cli.main import main

if __name__ == "__main__":
    main()
