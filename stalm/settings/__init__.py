"""A run's settings: one frozen tree (:mod:`~stalm.settings.tree`), read from and written to
text (:mod:`~stalm.settings.io`), and the flat choices of one planner
(:mod:`~stalm.settings.planner_config`). Every default of a run is written once, here."""
