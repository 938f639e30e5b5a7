"""``python -m odelab``: the same command line as ``odelab`` (for a venv whose scripts folder
is not on PATH, or to choose the interpreter: ``python3.12 -m odelab run ...``)."""

from odelab.cli import main

if __name__ == "__main__":  # pragma: no branch
    main()
