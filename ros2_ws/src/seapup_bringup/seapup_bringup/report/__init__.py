"""The reproduction report: the runs behind the thesis's targets (:mod:`~seapup_bringup.report.reproduction`) and
the document and page drawn from their scores (:mod:`~seapup_bringup.report.page`)."""
