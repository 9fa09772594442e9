"""Built-in method plugins; importing this package registers them."""

from . import lscm_igl, scp_igl  # noqa: F401
from . import sklearn_peers  # noqa: F401
from . import dncp_opt, scp  # noqa: F401
from . import lem, lle, ocp, pointcloud_peers, sdp  # noqa: F401
from . import bff_mouette, fbcp_pc  # noqa: F401
