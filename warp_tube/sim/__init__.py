"""Stage 4, the simulation: the frame loop (:mod:`.simulation`) and the contact monitor
(:mod:`.proximity`)."""
