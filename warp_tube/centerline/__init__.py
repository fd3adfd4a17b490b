"""Stage 3a, the centerline: semi-implicit Euler (:mod:`.explicit`), implicit Euler (:mod:`.implicit`)
and the stability bound (:mod:`.stability`)."""
