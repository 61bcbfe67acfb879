"""One online trial, shared by every method that acts online: the loop and its clock
(:mod:`~stalm.trial.online`, :mod:`~stalm.trial.episode`), what a trial returns
(:mod:`~stalm.trial.result`), its per-step log (:mod:`~stalm.trial.step_log`), the replay
that checks an executed plan (:mod:`~stalm.trial.replay`) and the seeds of model queries
(:mod:`~stalm.trial.query_seeds`)."""
