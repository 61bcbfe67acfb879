"""stalm: geometric task and motion planning guided by language models.

Imports flow one way, from geometry up to the command line, never down or sideways (checked
by the import-linter contract in ``pyproject.toml``):
geometry -> world -> motion -> domain | predicates -> llm | search -> settings -> proposers
-> trial -> planners -> generate -> experiments | viz -> api | cli.
"""

__version__ = "0.1.0"
