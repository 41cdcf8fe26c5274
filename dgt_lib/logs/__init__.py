"""Drive logs in: a robot's ROS bag read (:mod:`~dgt_lib.logs.bag`,
:mod:`~dgt_lib.logs.streams`), turned into the paper's BEV map and labelled patches
(:mod:`~dgt_lib.logs.ingest`), and the kit's own drives written as such logs to learn and
test with (:mod:`~dgt_lib.logs.record`). ``dgt log topics | record | ingest``."""
