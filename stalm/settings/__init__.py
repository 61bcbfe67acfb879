"""A run's settings: one frozen tree (:mod:`~stalm.settings.tree`), read from and written to
text (:mod:`~stalm.settings.io`). Every default of a run is written once, here."""
