"""stalm: geometric task and motion planning guided by language models.

The package follows a one-way import flow:
geometry -> world -> motion -> domain/predicates -> llm/search -> planners -> experiments -> cli.
"""

__version__ = "0.1.0"
