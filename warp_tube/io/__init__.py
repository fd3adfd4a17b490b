"""Stage 5, output: the USD writer (:mod:`.writer`), OBJ/glTF export (:mod:`.export`) and PNG previews
(:mod:`.preview`)."""
