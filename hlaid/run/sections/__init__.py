"""The sections of ``report.html`` (:func:`hlaid.run.report.build_report` puts them together), one
module each; every section renders a block of the typed run summary."""
