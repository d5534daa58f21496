"""Buildings: IFC models (read by :mod:`pycinder.files.ifc`, through IfcOpenShell) checked for
clashes between clash sets in the three query modes (:mod:`pycinder.bim.ifc`), and BCF out
(:mod:`pycinder.bim.bcf`). ``pycinder.ifc`` and
``pycinder.bcf`` are the same modules under their earlier names."""
