"""``python -m odelab.cli``: the ``odelab`` command."""

from odelab.cli.app import main

if __name__ == "__main__":  # pragma: no branch
    main()
