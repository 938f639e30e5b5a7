"""The lab's eq1 as Python. Grading must never import this file: importing it leaves a mark."""

import math
from pathlib import Path

Path(__file__).with_name("IMPORTED").write_text("eq1.py was imported\n")


def eq1(t, y):
    return [math.cos(t)]
