"""uqdrape.export: drape and ensemble results in the formats engineers open.

Plain functions, a result Dataset in and files out (lengths mm, angles degrees):

- :func:`export_vtk` -- the net as quads with its point data, and the mould, as ``.vtu``
- :func:`export_fe` -- fibre directions, shear (and ensemble spread) per element of an
  FE surface mesh, as ``.vtu`` cell data and an Abaqus ``*DISTRIBUTION`` table
- :func:`export_flat` -- the flat-blank position of every valid node and the blank
  outline, as CSV and DXF

A result is a ``uqdrape drape`` netCDF file or a ``uqdrape run`` folder
(:func:`open_result`); an ensemble is exported through its per-node statistics.
Every file is written under a temporary name and renamed only when all of them are
complete (``write_all`` of the ``*_files`` writers of several exports commits them
together), so a failed export leaves nothing half-written.
"""

from .directions import fibre_directions, fibre_frame
from .fe import export_fe, fe_files
from ..files import write_all
from .flat import export_flat, flat_files
from .result import Level, levels, open_result
from .vtk import export_vtk, vtk_files

__all__ = ["open_result", "levels", "Level", "fibre_directions", "fibre_frame", "export_vtk", "export_fe",
           "export_flat", "vtk_files", "fe_files", "flat_files", "write_all"]
