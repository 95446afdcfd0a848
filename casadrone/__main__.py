"""``python -m casadrone``: the command line, the same as the ``casadrone`` console script."""

from casadrone.cli import app

if __name__ == "__main__":
    app()
