"""The procedural surfaces, by dataset name."""

from .cap import Cap
from .cylinder import Cylinder
from .flat import Holes, Plane
from .gaps import Fold, Slit
from .gnome import GnomeStrip
from .graphs import Bump, HolesBumped, Saddle
from .protrusions import Protrusions

#: Dataset name -> Shape class, in the order ``dataset_names()`` lists them.
SHAPES = {cls.name: cls for cls in (Plane, Saddle, Bump, Holes, HolesBumped, Cap, Cylinder, Protrusions, GnomeStrip,
                                  Slit, Fold)}

__all__ = ["SHAPES"]
