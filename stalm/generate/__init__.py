"""Problem generation: solvable G-TAMP problems with witness plans, one or a suite of them."""
