"""Stage 3b, the surface: hubs-and-spokes rebuild orchestration (:mod:`.builder`) and the static
triangle topology (:mod:`.topology`)."""
