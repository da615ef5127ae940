"""One order carried out at run time (Sections 3.3-3.4): :func:`~repro.motion.runtime.strike.strike`
(retrieve, retarget, adapt) and the interactive fighter, with the paper's constants."""
