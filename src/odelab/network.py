"""Physical networks in Python: the elements as classes and :class:`Network`.

>>> from odelab.network import Network, Mass, Spring, Damper, ForceSource
>>> net = Network({"mass": Mass(node="p", m="m"), "spring": Spring(nodes=["p", "ground"], k="k"),
...                "damper": Damper(nodes=["p", "ground"], b="b"),
...                "push": ForceSource(nodes=["p", "ground"], value="f")},
...               outputs={"y": "q*mass.x"}, parameters={"m": 1, "k": 3, "b": 4, "q": 10})
>>> net.equations()["mass.v"]
'(f - b*mass.v - k*mass.x)/m'
>>> sys = net.compile()   # the StateSpace the TOML file gives

The same elements as ``[elements]`` in an experiment file (see docs/networks.md); SymPy is
imported only when a network is derived.
"""

from odelab.systems.network import *  # noqa: F401,F403
from odelab.systems.network import __all__  # noqa: F401
