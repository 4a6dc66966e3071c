"""uqdrape.export: drape and ensemble results in the formats engineers open.

Plain functions, a result Dataset in and files out (lengths mm, angles degrees):

- :func:`export_vtk` -- the net as quads with its point data, and the mould, as ``.vtu``
- :func:`export_fe` -- fibre directions, shear (and ensemble spread) per element of an
  FE surface mesh, as ``.vtu`` cell data and the cards of Abaqus, LS-DYNA or Nastran,
  both yarn directions per element
- :func:`export_laminate` -- a laminate ensemble's yarn angles per element and ply: the
  nominal layup and Monte Carlo decks as composite sections of Abaqus, LS-DYNA or
  Nastran, and the samples with their Karhunen-Loeve modes as CF netCDF
- :func:`export_flat` -- the flat-blank position of every valid node and the blank
  outline, as CSV and DXF
- :func:`export_cut` -- the cutting pattern: the part's edge in the flat blank, in the
  fabric's axes, with fibre marker, seed and ply label (and an ensemble's envelope), as
  DXF and CSV
- :func:`netcdf_file` -- the whole result as one CF netCDF file (a run's ensemble,
  streamed from its chunks)

A result is a ``uqdrape drape`` netCDF file or a ``uqdrape run`` folder or store URL
(:func:`open_result`); an ensemble is exported through its per-node statistics.
Every file is written under a temporary name and renamed only when all of them are
complete (``write_all`` of the ``*_files`` writers of several exports commits them
together), so a failed export leaves nothing half-written.
"""

from .cutting import cut_files, export_cut
from .directions import fibre_directions, fibre_frame
from .fe import export_fe, fe_files
from ..files import write_all
from .flat import export_flat, flat_files
from .laminate import export_laminate, laminate_files
from .result import Level, levels, netcdf_file, open_result
from .vtk import export_vtk, vtk_files

__all__ = ["open_result", "levels", "Level", "fibre_directions", "fibre_frame", "export_vtk", "export_fe",
           "export_laminate", "export_flat", "export_cut", "vtk_files", "fe_files", "laminate_files", "flat_files",
           "cut_files", "write_all", "netcdf_file"]
