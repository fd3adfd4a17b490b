"""Stage 2, the model: TubeModel/State/Control built from a Scene (:mod:`.tube`) and the NumPy
frame toolkit of rest geometry (:mod:`.frames`)."""
