"""Run records: what a run of the pipeline leaves for the reader, and the tables made
from them.

Every seed of ``dgt reproduce`` writes one small JSON record (:mod:`.record`): the
profile, seed, commit, processor, library versions and date (:mod:`.provenance`), every
experiment's counts and routes, the models' test errors, the costmaps' accuracy against
the measured ground truth, and each of the paper's claims checked in that seed. The
records a document rests on are published into ``docs/runs/<run>/`` and the README's and
docs' result tables are rendered from them (:mod:`.tables`, :mod:`.claims`) by ``make
docs`` (:mod:`.documents`), so that no result number in them is typed by hand.
"""
