"""The runtime type checker the tests install on drawer_lib: beartype with PEP 484's implicit
numeric tower (an int is a valid float), as the annotations intend."""

from beartype import BeartypeConf, beartype

typechecker = beartype(conf=BeartypeConf(is_pep484_tower=True))
