"""The safe expression language of experiment files.

Right-hand sides, exact solutions, outputs, parameters and time values in experiment files are
strings such as ``"-k/m*x - c*v + u"`` or ``"2*pi"``. The language is deliberately small:

* numbers (all evaluated as ``np.float64``) and names (``t``, states, inputs, parameters and the
  constants ``pi`` and ``e``); names are case-sensitive;
* ``+ - * /``, unary ``-``/``+``, parentheses, and power written ``^`` (as MATLAB users do) or
  ``**``; ``-x^2`` is ``-(x^2)`` as in MATLAB and Python;
* comparisons ``< <= > >= == !=`` evaluating to 1.0 or 0.0; a chain ``0 < t < 1`` means
  "and";
* the functions in :data:`FUNCTIONS`.

Nothing else: no attributes, indexing, other calls, keywords, strings, lambdas, comprehensions,
``and``/``or``/``not``, conditional expressions or complex literals. MATLAB groups ``a^b^c``
left to right and Python right to left, so an unparenthesised chain of powers that uses ``^`` is
rejected rather than silently read one way.

An expression is parsed once with :mod:`ast`, checked against a whitelist of node types, and
turned into Python source that only names its arguments and numpy helpers. That source is
compiled with empty builtins into a plain function, so evaluating costs about as much as the
arithmetic itself and no expression can reach anything outside the language. Evaluation ignores
floating-point errors (``1/0`` is inf, ``9^9^9`` cannot be written, ``9**9**9`` is inf): a
non-finite value is the solver's business, not an exception.

Every error is an :class:`~odelab.exceptions.ExpressionError` carrying the user's text and the
0-based column of the offending part, so the CLI can print a caret under it.
"""

from odelab.expressions.compile import (
    CompiledExpression,
    compile_expression,
    compile_vector,
)
from odelab.expressions.constants import (
    check_identifier,
    evaluate_constant,
    evaluate_parameters,
)
from odelab.expressions.functions import CONSTANTS, FUNCTIONS, RESERVED
from odelab.expressions.parse import (
    MAX_DEPTH,
    MAX_LENGTH,
    ParsedExpression,
    parse_expression,
)

__all__ = [
    "FUNCTIONS",
    "CONSTANTS",
    "RESERVED",
    "MAX_LENGTH",
    "MAX_DEPTH",
    "ParsedExpression",
    "CompiledExpression",
    "check_identifier",
    "parse_expression",
    "compile_expression",
    "compile_vector",
    "evaluate_constant",
    "evaluate_parameters",
]
