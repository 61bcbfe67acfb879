"""Where a step's batch of task plans comes from: a language model
(:mod:`~stalm.proposers.language_model`), Fast Downward on the predicate PDDL
(:mod:`~stalm.proposers.fast_downward`), or either with Figure 5's errors made on purpose
(:mod:`~stalm.proposers.noisy`); and the geometric feedback a proposer may be told
(:mod:`~stalm.proposers.feedback`, remembered by :mod:`~stalm.proposers.feedback_memory`)."""
