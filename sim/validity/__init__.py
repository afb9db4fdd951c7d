"""Where each fidelity is valid, measured: every rung's force against the FE reference over a table of samples
(thickness, depth, Poisson ratio, a skin over a base, an on-axis lump, distance to an edge).

:mod:`.cases` lists the samples and turns each into a scene; :mod:`.reference` computes and caches the FE answers
(models/reference_tables.json); :mod:`.measure` runs the rungs and measures the validity table
(models/validity_table.json; read and written as data by :mod:`.table`) that ``palpate bench`` prints and ``auto``
reads (:mod:`.choice`); :mod:`.offaxis` compares the contact law with the 3-D FE beside off-axis box lumps and
over a scene's buried box (not part of the table).
"""
