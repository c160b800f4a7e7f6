"""Studies, at their old import path: the code lives in :mod:`nurbsmotion.study`
(``spec``, ``case``, ``dataset``, ``execute``, ``run``, ``digest``); this module
re-exports its public names, so ``nurbsmotion.campaign.run_study`` and
``nurbsmotion.campaign.run_case`` keep working."""

from .study.case import case_trace, run_case
from .study.dataset import CAMPAIGN_OUTPUTS, read_rows
from .study.digest import (SUMMARY_FIGURES, digest, digest_markdown, make_digest,
                           write_digest)
from .study.execute import DASK_SETTINGS
from .study.run import CampaignResult, run_study
from .study.spec import (CASE_TIME_LIMIT, FEED_UNITS, STATUS_ERROR, STATUS_OK, WORKER_DIED,
                         Case, PlantGroup, RandomPaths, Study, find_case, load_study,
                         study_cases)

__all__ = ["Study", "Case", "load_study", "study_cases", "run_case", "run_study",
           "read_rows", "digest", "make_digest", "write_digest", "case_trace", "find_case", "STATUS_OK",
           "STATUS_ERROR", "WORKER_DIED", "DASK_SETTINGS", "PlantGroup", "RandomPaths",
           "CampaignResult", "CAMPAIGN_OUTPUTS", "CASE_TIME_LIMIT", "FEED_UNITS",
           "SUMMARY_FIGURES", "digest_markdown"]
