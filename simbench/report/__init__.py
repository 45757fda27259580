"""Reports of runs: figures, pictures, Markdown and self-contained HTML.

- :mod:`~simbench.report.plots`: the matplotlib figures (``save_figure`` writes a PNG atomically).
- :mod:`~simbench.report.pictures`: MuJoCo offscreen pictures of joint centres.
- :mod:`~simbench.report.markdown`: Markdown tables; Markdown to one HTML page, images embedded.
- :mod:`~simbench.report.output`: the files of a report folder (``index.md``, ``index.html``,
  ``results.json``).
- :mod:`~simbench.report.validation`: the validation report (``write_report``).
- :mod:`~simbench.report.dataset`: the report of one recording (``dataset_report``).
- :mod:`~simbench.report.study`: the study (sweep) summary.
"""
