"""Buildings: IFC models (read by :mod:`pycinder.files.ifc_elements`, through IfcOpenShell) checked
for clashes between clash sets in the three query modes (:mod:`pycinder.bim.ifc`); the clashes
grouped (:mod:`pycinder.bim.groups`), pictured (:mod:`pycinder.bim.snapshot`), tracked from one
run to the next (:mod:`pycinder.bim.tracking`), reported (:mod:`pycinder.bim.report`), and BCF
out (:mod:`pycinder.bim.bcf`). ``pycinder.ifc`` and ``pycinder.bcf`` are the same modules under
their earlier names."""
