"""Buildings: IFC in (:mod:`pycinder.bim.ifc`, through IfcOpenShell), clash sets and the three
query modes over them, and BCF out (:mod:`pycinder.bim.bcf`). ``pycinder.ifc`` and
``pycinder.bcf`` are the same modules under their earlier names."""
