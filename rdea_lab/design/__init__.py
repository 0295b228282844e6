"""Design studies: sweeps, sensitivity and optimization of roll geometry and bias, on dask.distributed.

The layer between calibration and reports (DESIGN.md): `load_study` reads a
study file (`rdea_lab.specs.study`), `run_study` samples and evaluates its
designs (`rdea_lab.design.evaluate`, vectorized over designs through
`rdea_lab.physics.designs`) on a cluster (`rdea_lab.design.cluster`), ranks
them (feasibility, Pareto front, Sobol indices) and refines the best
(`optimize`), and `StudyResult.write` writes the dataset, the tables, the figures and
the best design's specimen card.
"""

from .cluster import SchedulerError, StudyAborted, connect
from .study import StudyError, StudyResult, card_of, evaluate_table, feasible, pareto, run_study, sample

__all__ = ["SchedulerError", "StudyAborted", "StudyError", "StudyResult", "card_of", "connect", "evaluate_table",
           "feasible", "pareto", "run_study", "sample"]
