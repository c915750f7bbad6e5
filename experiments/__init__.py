"""The sweep files of the study, installed with the package as ``sb3_affect.sweeps`` (``sb3-affect run paper``)."""
