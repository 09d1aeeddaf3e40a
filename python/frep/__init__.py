"""frep - Python bindings of libfrep (ctypes over the public C API of frep.h).

Compile HyperFun / frep models, evaluate them on numpy arrays (the arrays' own
memory is handed to the library: no copies), enclose them over boxes, polygonize
them into indexed triangle meshes, sample their surfaces, read and write point
clouds and meshes.  Files written are byte-identical to the frep command's for the
same options and seed.

The library is found through FREP_LIBRARY (a path), pkg-config's libdir of frep,
or ctypes.util.find_library("frep").
"""
import ctypes
import ctypes.util
import os
import subprocess
import warnings

import numpy as np

__all__ = ["FrepError", "Program", "Mesh", "Cloud", "Segmentation", "Fit", "compile",
           "compile_file", "read_cloud", "read_mesh", "normals", "fit", "fit_file", "read_prims",
           "Evolution", "EvolveBase", "EVOLVE_PHASES", "Image", "library_version",
           "load_library"]

_c_double_p = ctypes.POINTER(ctypes.c_double)


class FrepError(Exception):
    """A failure of libfrep; .diagnostics holds the formatted messages."""

    def __init__(self, message, diagnostics=()):
        super().__init__(message)
        self.diagnostics = list(diagnostics)


# ---- the library ---------------------------------------------------------------

def _candidates():
    env = os.environ.get("FREP_LIBRARY")
    if env:
        yield env
        return
    try:
        libdir = subprocess.run(["pkg-config", "--variable=libdir", "frep"],
                                capture_output=True, text=True, check=True).stdout.strip()
        if libdir:
            for name in ("libfrep.so.0", "libfrep.so", "libfrep.dylib"):
                path = os.path.join(libdir, name)
                if os.path.exists(path):
                    yield path
    except (OSError, subprocess.CalledProcessError):
        pass
    found = ctypes.util.find_library("frep")
    if found:
        yield found


def load_library():
    """The loaded libfrep (ctypes.CDLL); raises OSError when none is found."""
    tried = []
    for path in _candidates():
        try:
            return ctypes.CDLL(path)
        except OSError as e:
            tried.append("%s (%s)" % (path, e))
    raise OSError("libfrep not found: set FREP_LIBRARY to the path of libfrep.so.0, or "
                  "install frep where pkg-config finds frep.pc" +
                  ("; tried " + ", ".join(tried) if tried else ""))


class _Diag(ctypes.Structure):
    _fields_ = [("severity", ctypes.c_int), ("file", ctypes.c_char_p),
                ("line", ctypes.c_uint32), ("col", ctypes.c_uint32),
                ("len", ctypes.c_uint32), ("message", ctypes.c_char_p)]


_DIAG_FN = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.POINTER(_Diag))
FREP_NOTE, FREP_WARNING, FREP_ERROR = 0, 1, 2


class _CompileOptions(ctypes.Structure):
    _fields_ = [("model", ctypes.c_char_p), ("a", _c_double_p), ("na", ctypes.c_size_t),
                ("setops_override", ctypes.c_int), ("alpha", ctypes.c_double),
                ("optimize", ctypes.c_int), ("strict", ctypes.c_int)]


class _RuntimeError(ctypes.Structure):
    _fields_ = [("count", ctypes.c_uint64), ("pc", ctypes.c_uint32),
                ("what", ctypes.c_char_p), ("x", ctypes.c_double), ("y", ctypes.c_double),
                ("z", ctypes.c_double)]


# frep_grid_options and frep_grid_summary (frep eval --grid)
class _GridOptions(ctypes.Structure):
    _fields_ = [("n", ctypes.c_long), ("has_box", ctypes.c_int), ("box", ctypes.c_double * 6),
                ("prune", ctypes.c_int), ("single", ctypes.c_int), ("nthreads", ctypes.c_int)]


class _GridSummary(ctypes.Structure):
    _fields_ = [("box", ctypes.c_double * 6), ("points", ctypes.c_uint64),
                ("inside", ctypes.c_uint64), ("nans", ctypes.c_uint64),
                ("min", ctypes.c_double), ("max", ctypes.c_double), ("sum", ctypes.c_double),
                ("insns", ctypes.c_double), ("threads", ctypes.c_int),
                ("precision", ctypes.c_int), ("single_blocks", ctypes.c_uint64),
                ("redone_blocks", ctypes.c_uint64), ("errors", _RuntimeError)]


_GRID_PRECISION = ("double", "double (no AVX2)", "double (operations the float path lacks)",
                   "single")


_PROGRESS_FN = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_double)


class _MeshOptions(ctypes.Structure):
    _fields_ = [("box", ctypes.c_double * 6), ("has_box", ctypes.c_int), ("grid", ctypes.c_int),
                ("iso", ctypes.c_double), ("params", _c_double_p), ("nthreads", ctypes.c_int),
                ("progress", _PROGRESS_FN), ("progress_user", ctypes.c_void_p),
                ("grid_axes", ctypes.c_int * 3), ("cancel_flag", ctypes.c_void_p)]


class _MeshInfo(ctypes.Structure):
    _fields_ = [("box", ctypes.c_double * 6), ("grid", ctypes.c_int),
                ("points_nan", ctypes.c_size_t), ("touches_box", ctypes.c_int),
                ("full", ctypes.c_int), ("seconds", ctypes.c_double)] + \
               [(n, ctypes.c_size_t) for n in ("octree_nodes", "blocks", "blocks_total",
                                               "eval_points", "grad_points", "cells_split",
                                               "face_vertices", "settled")] + \
               [(n, ctypes.c_double) for n in ("octree_seconds", "contour_seconds",
                                               "quads_seconds", "assembly_seconds",
                                               "settle_seconds")] + \
               [("interrupted", ctypes.c_int)]


class _MeshCheck(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in ("open_edges", "nonmanifold_edges",
                                               "flipped_edges", "nonmanifold_verts",
                                               "unused_verts", "degenerate", "nonfinite")] + \
               [("volume", ctypes.c_double), ("area", ctypes.c_double),
                ("self_intersections", ctypes.c_size_t)]


class _SampleOptions(ctypes.Structure):
    _fields_ = [("n", ctypes.c_size_t), ("seed", ctypes.c_uint64), ("noise", ctypes.c_double),
                ("noise_absolute", ctypes.c_int), ("outliers", ctypes.c_double),
                ("mesh", _MeshOptions)]


_SEG_PROGRESS_FN = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_size_t,
                                    ctypes.c_size_t, ctypes.c_size_t)
_SEG_CANCEL_FN = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p)


class _SegmentOptions(ctypes.Structure):
    _fields_ = [("epsilon", ctypes.c_double), ("cluster", ctypes.c_double),
                ("normal_deg", ctypes.c_double), ("min_points", ctypes.c_size_t),
                ("min_points_small", ctypes.c_size_t), ("probability", ctypes.c_double),
                ("types", ctypes.c_uint), ("seed", ctypes.c_uint64), ("nthreads", ctypes.c_int),
                ("knn", ctypes.c_size_t), ("separating", ctypes.c_int),
                ("progress", _SEG_PROGRESS_FN), ("cancel", _SEG_CANCEL_FN),
                ("user", ctypes.c_void_p), ("cancel_flag", ctypes.c_void_p)]


class _SegmentInfo(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in ("npoints", "nprims", "nfitted", "unassigned")] + \
               [(n, ctypes.c_double) for n in ("diagonal", "noise", "epsilon", "cluster",
                                               "normal_deg", "probability")] + \
               [("min_points", ctypes.c_size_t), ("min_points_small", ctypes.c_size_t),
                ("normals_estimated", ctypes.c_int), ("zero_normals", ctypes.c_size_t),
                ("draws", ctypes.c_size_t), ("interrupted", ctypes.c_int)]


class _Prim(ctypes.Structure):
    _fields_ = [("type", ctypes.c_int), ("p", ctypes.c_double * 3), ("a", ctypes.c_double * 3),
                ("r", ctypes.c_double), ("R", ctypes.c_double), ("separating", ctypes.c_int),
                ("support", ctypes.c_size_t), ("rms", ctypes.c_double)]


class _NormalsOptions(ctypes.Structure):
    _fields_ = [("knn", ctypes.c_size_t), ("nthreads", ctypes.c_int),
                ("cancel_flag", ctypes.c_void_p)]


class _NormalsInfo(ctypes.Structure):
    _fields_ = [("knn", ctypes.c_size_t), ("spacing", ctypes.c_double),
                ("noise", ctypes.c_double), ("components", ctypes.c_size_t),
                ("flipped", ctypes.c_size_t), ("interrupted", ctypes.c_int)]


class _FitProgress(ctypes.Structure):
    _fields_ = [("phase", ctypes.c_int), ("chain", ctypes.c_long), ("nchains", ctypes.c_long),
                ("iteration", ctypes.c_long), ("best", ctypes.c_double),
                ("subset", ctypes.c_int), ("elapsed", ctypes.c_double)]


_FIT_PROGRESS_FN = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.POINTER(_FitProgress))


class _FitOptions(ctypes.Structure):
    _fields_ = [("method", ctypes.c_int), ("objective", ctypes.c_int),
                ("global_objective", ctypes.c_int), ("loss", ctypes.c_int),
                ("loss_scale", ctypes.c_double), ("sa_loss", ctypes.c_int),
                ("robust", ctypes.c_int), ("normals_weight", ctypes.c_double),
                ("seed", ctypes.c_uint64), ("max_time", ctypes.c_double),
                ("max_evals", ctypes.c_long), ("max_work", ctypes.c_uint64),
                ("sa_points", ctypes.c_size_t),
                ("sa_stall", ctypes.c_long), ("sa_chains", ctypes.c_long),
                ("sa_threshold", ctypes.c_double), ("nthreads", ctypes.c_int),
                ("lo", _c_double_p), ("hi", _c_double_p), ("nbounds", ctypes.c_size_t),
                ("progress", _FIT_PROGRESS_FN), ("cancel", _SEG_CANCEL_FN),
                ("user", ctypes.c_void_p)]


class _FitParam(ctypes.Structure):
    _fields_ = [("name", ctypes.c_char_p), ("index", ctypes.c_size_t)] + \
               [(n, ctypes.c_double) for n in ("start", "value", "lo", "hi", "sigma",
                                               "sensitivity")] + \
               [("warnings", ctypes.c_uint)]


class _FitInfo(ctypes.Structure):
    _fields_ = [("npoints", ctypes.c_size_t), ("nparams", ctypes.c_size_t)] + \
               [(n, ctypes.c_double) for n in ("objective", "rms", "max_dist", "within",
                                               "within_inliers", "diagonal", "noise")] + \
               [("outliers", ctypes.c_size_t), ("evals", ctypes.c_long),
                ("seconds", ctypes.c_double), ("converged", ctypes.c_int),
                ("interrupted", ctypes.c_int), ("status", ctypes.c_char_p),
                ("verdict", ctypes.c_char_p)]


FIT_METHODS = ("saqn", "qn", "sa", "lm")
FIT_OBJECTIVES = ("algebraic", "geometric")
FIT_LOSSES = ("l2", "huber", "cauchy", "geman")
FIT_WARNINGS = ("on_bound", "near_bound", "no_effect", "tiny_effect", "loose")


class _EvolveProgress(ctypes.Structure):
    _fields_ = [("phase", ctypes.c_int), ("generation", ctypes.c_uint32),
                ("best_fitness", ctypes.c_double), ("tree_size", ctypes.c_uint32),
                ("explained", ctypes.c_size_t), ("npoints", ctypes.c_size_t),
                ("elapsed", ctypes.c_double)]


_EVOLVE_PROGRESS_FN = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.POINTER(_EvolveProgress))
_EVOLVE_TRACE_FN = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p)
EVOLVE_PHASES = ("ga", "merge", "merged", "grown", "cliques", "simplify", "normals",
                 "segment", "search", "refit")


class _EvolveOptions(ctypes.Structure):
    _fields_ = [("seed", ctypes.c_uint64), ("nthreads", ctypes.c_int), ("setops", ctypes.c_int)] + \
               [(n, ctypes.c_uint32) for n in ("generations", "stagnation", "population",
                                               "tournament", "elite")] + \
               [(n, ctypes.c_double) for n in ("crossover", "mutation", "subtree_prob")] + \
               [("max_depth", ctypes.c_int), ("max_time", ctypes.c_double),
                ("partition", ctypes.c_int), ("polish", ctypes.c_int),
                ("polish_stagnation", ctypes.c_uint32), ("simplify", ctypes.c_int),
                ("support", ctypes.c_int), ("sample", ctypes.c_size_t),
                ("epsilon", ctypes.c_double), ("alpha_deg", ctypes.c_double),
                ("lambda_scale", ctypes.c_double), ("knn", ctypes.c_size_t),
                ("refit", ctypes.c_int), ("report_explained", ctypes.c_int),
                ("progress", _EVOLVE_PROGRESS_FN), ("cancel", _SEG_CANCEL_FN),
                ("user", ctypes.c_void_p), ("cancel_flag", ctypes.c_void_p),
                ("trace", _EVOLVE_TRACE_FN), ("stop_share", ctypes.c_double),
                ("base", ctypes.c_void_p)]


class _EvolveInfo(ctypes.Structure):
    _fields_ = [("tree_size", ctypes.c_uint32)] + \
               [(n, ctypes.c_size_t) for n in ("nprims", "npoints", "dropped", "explained",
                                               "within_eps", "normals_ok")] + \
               [("fitness", ctypes.c_double), ("generations", ctypes.c_uint32),
                ("seconds", ctypes.c_double), ("alpha_deg", ctypes.c_double),
                ("alpha_auto", ctypes.c_int), ("partitioned", ctypes.c_int),
                ("interrupted", ctypes.c_int), ("refit_rms_before", ctypes.c_double),
                ("refit_rms_after", ctypes.c_double), ("refit_nparams", ctypes.c_size_t)] + \
               [(n, ctypes.c_double) for n in ("refit_max_before", "refit_max_after",
                                               "refit_seconds", "noise_spread",
                                               "noise_median_deg", "noise_p90_deg")] + \
               [("noise_inliers", ctypes.c_size_t), ("noisy", ctypes.c_int),
                ("base_explained", ctypes.c_size_t), ("base_failed", ctypes.c_size_t)]


class _RenderOptions(ctypes.Structure):
    _fields_ = [("width", ctypes.c_int), ("height", ctypes.c_int), ("view", ctypes.c_char_p),
                ("points", ctypes.c_void_p), ("scale", ctypes.c_double),
                ("plain", ctypes.c_int), ("program", ctypes.c_void_p),
                ("iso", ctypes.c_double), ("nthreads", ctypes.c_int),
                ("vertex_rgb", ctypes.c_void_p)]


class _RenderInfo(ctypes.Structure):
    _fields_ = [("ntris", ctypes.c_size_t), ("npoints", ctypes.c_size_t),
                ("mean_dist", ctypes.c_double), ("max_dist", ctypes.c_double),
                ("inside", ctypes.c_size_t), ("rings", ctypes.c_size_t),
                ("point_scale", ctypes.c_double), ("surface_scale", ctypes.c_double)]


class _Distances(ctypes.Structure):
    _fields_ = [("point", ctypes.POINTER(ctypes.c_double)),
                ("vertex", ctypes.POINTER(ctypes.c_double)),
                ("point_scale", ctypes.c_double), ("vertex_scale", ctypes.c_double)]


class _ViewScene(ctypes.Structure):
    _fields_ = [("name", ctypes.c_char_p), ("mesh", ctypes.c_void_p),
                ("vrgb", ctypes.c_void_p), ("vdist", _c_double_p), ("vscale", ctypes.c_double),
                ("npoints", ctypes.c_size_t), ("px", _c_double_p), ("py", _c_double_p),
                ("pz", _c_double_p), ("pdist", _c_double_p), ("pscale", ctypes.c_double),
                ("source", ctypes.c_char_p), ("nparams", ctypes.c_size_t),
                ("pnames", ctypes.POINTER(ctypes.c_char_p)), ("pvalues", _c_double_p),
                ("diag", ctypes.c_char_p), ("cdiag", ctypes.c_char_p), ("failed", ctypes.c_int),
                ("info", ctypes.c_char_p), ("units", ctypes.c_char_p),
                ("version", ctypes.c_uint)]


class _ScadOptions(ctypes.Structure):
    _fields_ = [("model", ctypes.c_char_p), ("a", ctypes.POINTER(ctypes.c_double)),
                ("na", ctypes.c_size_t), ("box", ctypes.c_double * 6), ("fn", ctypes.c_int),
                ("title", ctypes.c_char_p)]


PRIM_TYPES = ("plane", "sphere", "cylinder", "cone", "torus")
_MESH_FORMATS = {"auto": 0, "stl": 1, "obj": 2, "ply": 3, "off": 4, "wrl": 5}


def _declare(lib):
    P, S, D, I = ctypes.c_void_p, ctypes.c_size_t, ctypes.c_double, ctypes.c_int
    sig = {
        "frep_version": (ctypes.c_char_p, []),
        "frep_free": (None, [P]),
        "frep_diag_format": (P, [ctypes.POINTER(_Diag), ctypes.c_char_p, S]),
        "frep_compile_options_init": (None, [ctypes.POINTER(_CompileOptions)]),
        "frep_compile": (P, [ctypes.c_char_p, ctypes.c_char_p, S,
                             ctypes.POINTER(_CompileOptions), _DIAG_FN, P]),
        "frep_program_free": (None, [P]),
        "frep_program_size": (S, [P]),
        "frep_program_nparams": (S, [P]),
        "frep_program_na": (S, [P]),
        "frep_program_nfree": (S, [P]),
        "frep_program_param_index": (I, [P, ctypes.c_char_p, ctypes.POINTER(S)]),
        "frep_program_param_values": (I, [P, P, S]),
        "frep_program_param_name": (ctypes.c_char_p, [P, S]),
        "frep_program_param_bounds": (I, [P, S, ctypes.POINTER(D), ctypes.POINTER(D)]),
        "frep_program_box": (I, [P, ctypes.c_double * 6]),
        "frep_disassemble": (P, [P]),
        "frep_eval_par": (I, [P, S, P, P, P, P, P, I, ctypes.POINTER(_RuntimeError)]),
        "frep_eval_grad_par": (I, [P, S, P, P, P, P, P, P, P, P, I,
                                   ctypes.POINTER(_RuntimeError)]),
        "frep_report_runtime_error": (None, [P, ctypes.POINTER(_RuntimeError), _DIAG_FN, P]),
        "frep_interval_scratch_new": (P, [P]),
        "frep_interval_scratch_free": (None, [P]),
        "frep_eval_interval": (I, [P, P, ctypes.c_double * 6, P, ctypes.POINTER(D),
                                   ctypes.POINTER(D)]),
        "frep_grid_options_init": (None, [ctypes.POINTER(_GridOptions)]),
        "frep_eval_grid": (I, [P, ctypes.POINTER(_GridOptions), ctypes.POINTER(_GridSummary),
                               _DIAG_FN, P]),
        "frep_print_source": (P, [ctypes.c_char_p, ctypes.c_char_p, S, I, ctypes.POINTER(S),
                                  _DIAG_FN, P]),
        "frep_cloud_read": (P, [ctypes.c_char_p, _DIAG_FN, P]),
        "frep_cloud_new": (P, [S, P, P, P, P, P, P, _DIAG_FN, P]),
        "frep_cloud_free": (None, [P]),
        "frep_cloud_size": (S, [P]),
        "frep_cloud_has_normals": (I, [P]),
        "frep_cloud_arrays": (None, [P] + [ctypes.POINTER(_c_double_p)] * 6),
        "frep_cloud_write": (I, [P, ctypes.c_char_p, _DIAG_FN, P]),
        "frep_mesh_options_init": (None, [ctypes.POINTER(_MeshOptions)]),
        "frep_polygonize": (P, [P, ctypes.POINTER(_MeshOptions), ctypes.POINTER(_MeshInfo),
                                _DIAG_FN, P]),
        "frep_mesh_new": (P, [S, P, P, S, P, _DIAG_FN, P]),
        "frep_mesh_read": (P, [ctypes.c_char_p, _DIAG_FN, P]),
        "frep_mesh_free": (None, [P]),
        "frep_mesh_nverts": (S, [P]),
        "frep_mesh_ntris": (S, [P]),
        "frep_mesh_vertices": (_c_double_p, [P]),
        "frep_mesh_normals": (_c_double_p, [P]),
        "frep_mesh_triangles": (ctypes.POINTER(ctypes.c_uint32), [P]),
        "frep_mesh_write": (I, [P, ctypes.c_char_p, I, I, _DIAG_FN, P]),
        "frep_mesh_check": (I, [P, I, ctypes.POINTER(_MeshCheck), _DIAG_FN, P]),
        "frep_mesh_colors": (I, [P, P, D, D, P, I, ctypes.POINTER(ctypes.POINTER(ctypes.c_uint8)),
                                 ctypes.POINTER(_RuntimeError)]),
        "frep_sample_options_init": (None, [ctypes.POINTER(_SampleOptions)]),
        "frep_sample": (P, [P, ctypes.POINTER(_SampleOptions), _DIAG_FN, P]),
        "frep_sample_mesh": (P, [P, ctypes.POINTER(_SampleOptions), _DIAG_FN, P]),
        "frep_segment_options_init": (None, [ctypes.POINTER(_SegmentOptions)]),
        "frep_segment": (P, [P, ctypes.POINTER(_SegmentOptions), _DIAG_FN, P]),
        "frep_segmentation_free": (None, [P]),
        "frep_segmentation_nprims": (S, [P]),
        "frep_segmentation_nfitted": (S, [P]),
        "frep_segmentation_unassigned": (S, [P]),
        "frep_segmentation_interrupted": (I, [P]),
        "frep_segmentation_labels": (ctypes.POINTER(ctypes.c_int32), [P]),
        "frep_segmentation_write": (I, [P, ctypes.c_char_p, ctypes.c_char_p, _DIAG_FN, P]),
        "frep_segmentation_get_info": (None, [P, ctypes.POINTER(_SegmentInfo)]),
        "frep_segmentation_get_prim": (I, [P, S, ctypes.POINTER(_Prim)]),
        "frep_prim_type_name": (ctypes.c_char_p, [I]),
        "frep_cloud_check": (I, [P, ctypes.c_char_p, ctypes.POINTER(I), _DIAG_FN, P]),
        "frep_normals_options_init": (None, [ctypes.POINTER(_NormalsOptions)]),
        "frep_normals": (I, [P, ctypes.POINTER(_NormalsOptions), ctypes.POINTER(_NormalsInfo),
                             _DIAG_FN, P]),
        "frep_fit_options_init": (None, [ctypes.POINTER(_FitOptions)]),
        "frep_fit_template": (P, [ctypes.c_char_p, ctypes.c_char_p, S,
                                  ctypes.POINTER(_CompileOptions), P,
                                  ctypes.POINTER(_FitOptions), _DIAG_FN, P]),
        "frep_fit_free": (None, [P]),
        "frep_fit_nparams": (S, [P]),
        "frep_fit_nvalues": (S, [P]),
        "frep_fit_get_param": (I, [P, S, ctypes.POINTER(_FitParam)]),
        "frep_fit_get_info": (None, [P, ctypes.POINTER(_FitInfo)]),
        "frep_fit_values": (I, [P, P, S]),
        "frep_fit_text": (ctypes.c_char_p, [P, ctypes.POINTER(S)]),
        "frep_fit_write": (I, [P, ctypes.c_char_p, _DIAG_FN, P]),
        "frep_fit_write_json": (I, [P, ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p,
                                    ctypes.c_char_p, _DIAG_FN, P]),
        "frep_evolve_options_init": (None, [ctypes.POINTER(_EvolveOptions)]),
        "frep_segmentation_read": (P, [ctypes.c_char_p, _DIAG_FN, P]),
        "frep_evolve": (P, [P, P, ctypes.POINTER(_EvolveOptions), _DIAG_FN, P]),
        "frep_evolution_free": (None, [P]),
        "frep_evolution_get_info": (None, [P, ctypes.POINTER(_EvolveInfo)]),
        "frep_evolution_write": (I, [P, ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p,
                                     I, I, _DIAG_FN, P]),
        "frep_evolution_write_dot": (I, [P, ctypes.c_char_p, _DIAG_FN, P]),
        "frep_evolution_model": (P, [P, ctypes.c_char_p, ctypes.c_char_p, I, I,
                                     ctypes.POINTER(S), _DIAG_FN, P]),
        "frep_evolution_dot": (P, [P, ctypes.POINTER(S), _DIAG_FN, P]),
        "frep_evolve_base_new": (P, [P, ctypes.c_char_p, ctypes.c_char_p, S, ctypes.c_char_p,
                                     _DIAG_FN, P]),
        "frep_evolve_base_free": (None, [P]),
        "frep_evolve_base_setops": (I, [P]),
        "frep_render_options_init": (None, [ctypes.POINTER(_RenderOptions)]),
        "frep_render": (P, [P, ctypes.POINTER(_RenderOptions), ctypes.POINTER(_RenderInfo),
                            _DIAG_FN, P]),
        "frep_image_free": (None, [P]),
        "frep_image_pixels": (ctypes.POINTER(ctypes.c_uint8),
                              [P, ctypes.POINTER(I), ctypes.POINTER(I)]),
        "frep_image_write_png": (I, [P, ctypes.c_char_p, _DIAG_FN, P]),
        "frep_program_param_used": (I, [P, S]),
        "frep_cloud_distances": (I, [P, P, P, D, I, ctypes.POINTER(_Distances), _DIAG_FN, P]),
        "frep_distances_free": (None, [ctypes.POINTER(_Distances)]),
        "frep_scad_options_init": (None, [ctypes.POINTER(_ScadOptions)]),
        "frep_view_scene_init": (None, [ctypes.POINTER(_ViewScene)]),
        "frep_view_page": (P, [ctypes.POINTER(_ViewScene), I, ctypes.POINTER(S), _DIAG_FN, P]),
        "frep_export_scad": (P, [ctypes.c_char_p, ctypes.c_char_p, S,
                                 ctypes.POINTER(_ScadOptions), _DIAG_FN, P]),
        "frep_fit_method_name": (ctypes.c_char_p, [I]),
        "frep_fit_objective_name": (ctypes.c_char_p, [I]),
        "frep_fit_loss_name": (ctypes.c_char_p, [I]),
    }
    for name, (res, args) in sig.items():
        fn = getattr(lib, name)
        fn.restype = res
        fn.argtypes = args
    return lib


_lib = None


def _L():
    global _lib
    if _lib is None:
        _lib = _declare(load_library())
    return _lib


def library_version():
    """The version of the loaded libfrep, "MAJOR.MINOR.PATCH"."""
    return _L().frep_version().decode()


class _Diagnostics:
    """Collects the library's diagnostics, formatted as the frep command prints them;
    warnings go to Python's warnings module."""

    def __init__(self, source=None):
        self.source = source
        self.messages = []
        self.errors = []
        self.fn = _DIAG_FN(self._on)

    def _on(self, user, d):
        lib = _L()
        src = self.source or b""
        p = lib.frep_diag_format(d, src if self.source else None, len(src))
        text = ctypes.string_at(p).decode(errors="replace").rstrip("\n") if p else \
            (d.contents.message or b"").decode(errors="replace")
        lib.frep_free(p)
        self.messages.append(text)
        if d.contents.severity == FREP_ERROR:
            self.errors.append(text)
        elif d.contents.severity == FREP_WARNING:
            warnings.warn(text, RuntimeWarning, stacklevel=3)

    def fail(self, what):
        msg = what + (": " + "\n".join(self.errors) if self.errors else "")
        raise FrepError(msg, self.messages)


def _f64(a, n=None, name="array"):
    """a as a contiguous float64 array (no copy when it already is one)."""
    a = np.ascontiguousarray(a, dtype=np.float64)
    if a.ndim != 1 or (n is not None and a.shape[0] != n):
        raise ValueError("%s: expected a 1-D array of %s values" % (name, n if n else "N"))
    return a


def _box6(box):
    """A box argument as six numbers: a number v is [-v, v]^3, else
    (x0, y0, z0, x1, y1, z1)."""
    b = [float(box)] if np.isscalar(box) else [float(v) for v in box]
    if len(b) == 1:
        b = [-b[0]] * 3 + [b[0]] * 3
    if len(b) != 6:
        raise ValueError("box: a number v ([-v, v]^3) or (x0, y0, z0, x1, y1, z1)")
    return b


def _ptr(a):
    return ctypes.c_void_p(a.ctypes.data) if a is not None else None


class _Handle:
    """A library object and the function that frees it: what numpy views of its
    memory keep alive (no reference cycle with the Python wrapper)."""

    def __init__(self, ptr, free):
        self.ptr = ptr
        self._free = free

    def __del__(self):
        if self.ptr:
            self._free(self.ptr)
            self.ptr = None


class _Wrapper:
    """The Python side of one library object that a subclass's _set(h) takes over:
    from a fresh handle (_adopt, failing with the diagnostics when it is NULL) or from
    one a library call returned (_own)."""

    @classmethod
    def _own(cls, h):
        obj = cls.__new__(cls)
        obj._set(h)
        return obj

    def _adopt(self, h, diagnostics, what):
        if not h:
            diagnostics.fail(what)
        self._set(h)


# ---- programs ----------------------------------------------------------------------

class Program:
    """A compiled model: immutable, may be shared by threads."""

    def __init__(self, handle, source, name):
        self._handle = _Handle(handle, _L().frep_program_free)
        self._h = handle
        self.source = source
        self.name = name

    @property
    def size(self):
        """Instructions of the bytecode."""
        return _L().frep_program_size(self._h)

    @property
    def nparams(self):
        """Length of the parameter vector: the elements of a[] then the named @free."""
        return _L().frep_program_nparams(self._h)

    @property
    def param_names(self):
        """Names in vector order: "a[1]", ..., then the @free names."""
        lib = _L()
        return [lib.frep_program_param_name(self._h, i).decode() for i in range(self.nparams)]

    def param_index(self, name):
        """Index in the parameter vector of "r" (a named @free parameter) or "a[2]"."""
        i = ctypes.c_size_t()
        if _L().frep_program_param_index(self._h, name.encode(), ctypes.byref(i)) != 0:
            raise KeyError("the model has no parameter %r (it has %s)" %
                           (name, ", ".join(self.param_names) or "none"))
        return i.value

    def param_values(self):
        """The program's own parameter vector (a new array)."""
        v = np.zeros(max(self.nparams, 1))
        _L().frep_program_param_values(self._h, _ptr(v), v.shape[0])
        return v[:self.nparams]

    @property
    def params(self):
        """{name: value} of the program's own parameters."""
        return dict(zip(self.param_names, self.param_values()))

    def param_bounds(self, name):
        """(lo, hi) of a parameter, or None without bounds."""
        lo, hi = ctypes.c_double(), ctypes.c_double()
        if _L().frep_program_param_bounds(self._h, self.param_index(name), ctypes.byref(lo),
                                          ctypes.byref(hi)):
            return lo.value, hi.value
        return None

    def param_used(self, name):
        """Whether the model's code reads parameter `name` (as param_index takes it):
        an element of a[] the model never reads is False."""
        return bool(_L().frep_program_param_used(self._h, self.param_index(name)))

    def box(self):
        """The model's `-- @box` (x0, y0, z0, x1, y1, z1), or None."""
        b = (ctypes.c_double * 6)()
        return tuple(b) if _L().frep_program_box(self._h, b) else None

    def disassemble(self):
        p = _L().frep_disassemble(self._h)
        try:
            return ctypes.string_at(p).decode()
        finally:
            _L().frep_free(p)

    def _params(self, params):
        """The parameter vector to pass: None (the program's own), a {name: value}
        dict applied over the program's values, or a full vector."""
        if params is None:
            return None
        if isinstance(params, dict):
            v = self.param_values()
            for k, x in params.items():
                v[self.param_index(k)] = x
            return v
        return _f64(params, self.nparams, "params")

    def _runtime(self, err):
        if err.count:
            d = _Diagnostics(self.source)
            _L().frep_report_runtime_error(self._h, ctypes.byref(err), d.fn, None)
            for m in d.messages:
                warnings.warn(m, RuntimeWarning, stacklevel=3)

    def eval(self, x, y=None, z=None, params=None, threads=0, out=None):
        """f at the points (x[i], y[i], z[i]): three 1-D arrays (used in place when
        contiguous float64) or one (N, 3) array (its columns are copied).  params: None,
        {name: value} or the full vector.  Points with runtime domain errors are NaN (a
        RuntimeWarning says where in the model)."""
        x, y, z = self._xyz(x, y, z)
        n = x.shape[0]
        f = np.empty(n) if out is None else out
        if f.dtype != np.float64 or f.shape != (n,) or not f.flags.c_contiguous:
            raise ValueError("out: a contiguous float64 array of %d values" % n)
        pv = self._params(params)
        err = _RuntimeError()
        if _L().frep_eval_par(self._h, n, _ptr(x), _ptr(y), _ptr(z), _ptr(pv), _ptr(f),
                              threads, ctypes.byref(err)) != 0:
            raise FrepError("evaluation failed (out of memory)")
        self._runtime(err)
        return f

    def grad(self, x, y=None, z=None, params=None, threads=0):
        """(f, g): values and gradients, g an (N, 3) array (forward-mode AD)."""
        x, y, z = self._xyz(x, y, z)
        n = x.shape[0]
        f = np.empty(n)
        g = np.empty((3, n))
        pv = self._params(params)
        err = _RuntimeError()
        if _L().frep_eval_grad_par(self._h, n, _ptr(x), _ptr(y), _ptr(z), _ptr(pv), _ptr(f),
                                   _ptr(g[0]), _ptr(g[1]), _ptr(g[2]), threads,
                                   ctypes.byref(err)) != 0:
            raise FrepError("evaluation failed (out of memory)")
        self._runtime(err)
        return f, g.T

    @staticmethod
    def _xyz(x, y, z):
        if y is None and z is None:
            pts = np.asarray(x, dtype=np.float64)
            if pts.ndim != 2 or pts.shape[1] != 3:
                raise ValueError("points: expected an (N, 3) array, or x, y, z")
            return (np.ascontiguousarray(pts[:, 0]), np.ascontiguousarray(pts[:, 1]),
                    np.ascontiguousarray(pts[:, 2]))
        x = _f64(x, None, "x")
        return x, _f64(y, x.shape[0], "y"), _f64(z, x.shape[0], "z")

    def interval(self, box, params=None):
        """(lo, hi) enclosing f over box (x0, y0, z0, x1, y1, z1)."""
        lib = _L()
        s = lib.frep_interval_scratch_new(self._h)
        if not s:
            raise FrepError("out of memory")
        try:
            lo, hi = ctypes.c_double(), ctypes.c_double()
            pv = self._params(params)
            b = (ctypes.c_double * 6)(*[float(v) for v in box])
            if lib.frep_eval_interval(self._h, s, b, _ptr(pv), ctypes.byref(lo),
                                      ctypes.byref(hi)) != 0:
                raise FrepError("interval evaluation failed")
            return lo.value, hi.value
        finally:
            lib.frep_interval_scratch_free(s)

    def grid_summary(self, n=64, box=None, prune=True, single=False, threads=0):
        """The summary of `frep eval --grid n`: the values at n^3 points of the box
        (default the model's -- @box, else [-10, 10]^3), as a dict: box, points,
        inside (f >= 0), nans, min, max, sum, insns (instructions x points), threads,
        precision, single_blocks, redone_blocks, errors (points with runtime errors)."""
        lib = _L()
        o = _GridOptions()
        lib.frep_grid_options_init(ctypes.byref(o))
        o.n = int(n)
        if box is not None:
            o.box[:] = _box6(box)
            o.has_box = 1
        o.prune = 1 if prune else 0
        o.single = 1 if single else 0
        o.nthreads = int(threads)
        g = _GridSummary()
        d = _Diagnostics(self.source)
        if lib.frep_eval_grid(self._h, ctypes.byref(o), ctypes.byref(g), d.fn, None) != 0:
            d.fail("cannot evaluate the grid")
        return {"box": tuple(g.box), "points": g.points, "inside": g.inside, "nans": g.nans,
                "min": g.min, "max": g.max, "sum": g.sum, "insns": g.insns,
                "threads": g.threads, "precision": _GRID_PRECISION[g.precision],
                "single_blocks": g.single_blocks, "redone_blocks": g.redone_blocks,
                "errors": g.errors.count}

    def _mesh_options(self, o, box, grid, iso, params, threads):
        if box is not None:
            o.box[:] = _box6(box)
            o.has_box = 1
        if grid is not None:
            o.grid = int(grid)
        o.iso = float(iso)
        o.nthreads = int(threads)
        pv = self._params(params)
        o.params = ctypes.cast(_ptr(pv), _c_double_p) if pv is not None else None
        return pv    # kept alive by the caller

    def mesh(self, grid=64, box=None, iso=0.0, params=None, threads=0):
        """Polygonize f = iso (as frep mesh -g GRID): a Mesh.  box: None (the model's
        `-- @box`, else [-10, 10]^3), a number v or (x0, y0, z0, x1, y1, z1)."""
        lib = _L()
        o = _MeshOptions()
        lib.frep_mesh_options_init(ctypes.byref(o))
        keep = self._mesh_options(o, box, grid, iso, params, threads)
        info = _MeshInfo()
        d = _Diagnostics(self.source)
        h = lib.frep_polygonize(self._h, ctypes.byref(o), ctypes.byref(info), d.fn, None)
        del keep
        if not h:
            d.fail("polygonization failed")
        m = Mesh._own(h)
        m.info = {k: getattr(info, k) for k, _ in _MeshInfo._fields_ if k != "box"}
        m.info["box"] = tuple(info.box)
        return m

    def colors(self, mesh, cell, iso=0.0, params=None, threads=0):
        """The model's colours (s[1..3], e.g. hfA_SetColor) at the vertices of mesh, as
        frep mesh writes them into PLY: an (N, 3) uint8 array, or None when the model has
        no colours.  cell: the mesh's cell side (the box side / grid)."""
        lib = _L()
        rgb = ctypes.POINTER(ctypes.c_uint8)()
        err = _RuntimeError()
        pv = self._params(params)
        if lib.frep_mesh_colors(self._h, mesh._h, float(cell), float(iso), _ptr(pv),
                                int(threads), ctypes.byref(rgb), ctypes.byref(err)) != 0:
            raise FrepError("out of memory")
        self._runtime(err)
        if not rgb:
            return None
        try:
            n = lib.frep_mesh_nverts(mesh._h)
            return np.ctypeslib.as_array(rgb, shape=(n, 3)).copy()
        finally:
            lib.frep_free(rgb)

    def sample(self, n, seed=1, noise=0.0, noise_absolute=False, outliers=0.0, grid=None,
               box=None, iso=0.0, params=None, threads=0):
        """n points on the surface with outward normals (as frep sample): a Cloud.
        noise: standard deviation, times the box diagonal (or model units with
        noise_absolute); outliers: fraction of points uniform in the box."""
        lib = _L()
        o = _SampleOptions()
        lib.frep_sample_options_init(ctypes.byref(o))
        o.n, o.seed, o.noise = int(n), int(seed), float(noise)
        o.noise_absolute, o.outliers = int(bool(noise_absolute)), float(outliers)
        keep = self._mesh_options(o.mesh, box, grid, iso, params, threads)
        d = _Diagnostics(self.source)
        h = lib.frep_sample(self._h, ctypes.byref(o), d.fn, None)
        del keep
        if not h:
            d.fail("sampling failed")
        return Cloud._own(h)


def _set_model_a(o, model, a):
    """The model's name and the values of a[] into options o (frep_compile_options,
    frep_scad_options); returns the arrays to keep alive."""
    keep = []
    if model:
        o.model = model.encode()
    if a is not None:
        av = _f64(a, None, "a")
        keep.append(av)
        o.a = ctypes.cast(_ptr(av), _c_double_p)
        o.na = av.shape[0]
    return keep


def _compile_options(model=None, a=None, setops=None, optimize=True, strict=False):
    """frep_compile_options and the arrays it points to (keep them alive)."""
    o = _CompileOptions()
    _L().frep_compile_options_init(ctypes.byref(o))
    keep = _set_model_a(o, model, a)
    if setops is not None:
        o.setops_override = {"rfunc": 0, "minmax": 1}[setops]
    o.optimize = int(bool(optimize))
    o.strict = int(bool(strict))
    return o, keep


def compile(text, name="<string>", model=None, a=None, setops=None, optimize=True,
            strict=False):
    """Compile model source text.  model: which model (default my_model, else the last);
    a: values of a[]; setops: None, "rfunc", "minmax"; strict: what the reference
    HyperFun rejects is an error.  Raises FrepError with the compiler's messages."""
    lib = _L()
    src = text.encode() if isinstance(text, str) else bytes(text)
    o, keep = _compile_options(model, a, setops, optimize, strict)
    d = _Diagnostics(src)
    h = lib.frep_compile(name.encode(), src, len(src), ctypes.byref(o), d.fn, None)
    if not h:
        d.fail("cannot compile %s" % name)
    return Program(h, src, name)


def compile_file(path, **kw):
    """Compile the model file at path (see compile)."""
    with open(path, "rb") as f:
        return compile(f.read(), name=str(path), **kw)


def export_scad(text, name="<string>", model=None, a=None, box=None, fn=48, title=None):
    """The model text as OpenSCAD source, as `frep export` writes it: box, the box of
    an unbounded model (x0, y0, z0, x1, y1, z1), default the model's `-- @box`, else
    [-10, 10]^3 (as frep export); fn: $fn, 3..1024.  Raises FrepError with the
    construct that has no OpenSCAD equivalent, at its position."""
    lib = _L()
    src = text.encode() if isinstance(text, str) else bytes(text)
    o = _ScadOptions()
    lib.frep_scad_options_init(ctypes.byref(o))
    keep = _set_model_a(o, model, a)
    if box is None:
        box = compile(src, name=name, model=model, a=a).box()
    if box is not None:
        o.box = (ctypes.c_double * 6)(*[float(v) for v in box])
    o.fn = int(fn)
    if title is not None:
        o.title = title.encode()
    d = _Diagnostics(src)
    p = lib.frep_export_scad(name.encode(), src, len(src), ctypes.byref(o), d.fn, None)
    if not p:
        d.fail("cannot export %s" % name)
    try:
        return ctypes.string_at(p).decode()
    finally:
        lib.frep_free(p)


def view_page(mesh, cloud=None, program=None, name="", iso=0.0, scale=0.0, threads=0,
              colors=None, info=""):
    """The page of `frep view` as a string: one self-contained HTML file drawing mesh
    in WebGL, with cloud (a Cloud) coloured by its distances (see distances; to
    program's surface, else to the mesh), scale the point distance drawn red (0: from
    the data), program's text and parameters beside it, colors (nverts, 3) uint8 vertex
    colours.  For a mesh file and a cloud, the bytes frep view writes."""
    lib = _L()
    sc = _ViewScene()
    lib.frep_view_scene_init(ctypes.byref(sc))
    sc.name = str(name).encode()
    sc.mesh = mesh._h
    sc.info = info.encode() if info is not None else None
    keep = []
    if cloud is not None:
        d = distances(cloud, mesh, program, iso, threads)
        keep += [d["point"], d["vertex"]]
        sc.npoints = len(cloud)
        sc.px, sc.py, sc.pz = (ctypes.cast(_ptr(np.ascontiguousarray(a)), _c_double_p)
                               for a in (cloud.x, cloud.y, cloud.z))
        sc.pdist = ctypes.cast(_ptr(d["point"]), _c_double_p)
        sc.vdist = ctypes.cast(_ptr(d["vertex"]), _c_double_p)
        sc.pscale = scale if scale > 0 else d["point_scale"] if d["point_scale"] > 0 else 1.0
        sc.vscale = d["vertex_scale"] if d["vertex_scale"] > 0 else 1.0
    if program is not None:
        sc.source = program.source
        names = [n.encode() for n in program.param_names]
        values = np.ascontiguousarray(program.param_values(), dtype=np.float64)
        pn = (ctypes.c_char_p * max(len(names), 1))(*names)
        keep += [names, values, pn]
        sc.nparams = len(names)
        sc.pnames = ctypes.cast(pn, ctypes.POINTER(ctypes.c_char_p))
        sc.pvalues = ctypes.cast(_ptr(values), _c_double_p)
    if colors is not None:
        rgb = np.ascontiguousarray(colors, dtype=np.uint8).reshape(-1, 3)
        if rgb.shape[0] != mesh.vertices.shape[0]:
            raise ValueError("colors: one (r, g, b) per vertex")
        keep.append(rgb)
        sc.vrgb = rgb.ctypes.data
    n = ctypes.c_size_t()
    dg = _Diagnostics()
    p = lib.frep_view_page(ctypes.byref(sc), 0, ctypes.byref(n), dg.fn, None)
    if not p:
        dg.fail("cannot make the page")
    try:
        return ctypes.string_at(p, n.value).decode()
    finally:
        lib.frep_free(p)


def distances(cloud, mesh, program=None, iso=0.0, threads=0):
    """How far a Cloud is from a surface and the surface from the cloud, as frep view
    and frep render colour them: a dict with "point" (one signed distance a point, > 0
    inside: |f - iso|/|grad f| of program, or to mesh's nearest triangle without one),
    "vertex" (each vertex of mesh to the nearest point) and their colour scales
    "point_scale", "vertex_scale" (0 when no distance is finite and positive)."""
    lib = _L()
    r = _Distances()
    d = _Diagnostics(program.source if program is not None else None)
    if lib.frep_cloud_distances(cloud._h, mesh._h, program._h if program is not None else None,
                                float(iso), int(threads), ctypes.byref(r), d.fn, None) != 0:
        d.fail("cannot measure the cloud")
    try:
        n, nv = len(cloud), mesh.vertices.shape[0]
        return {"point": np.ctypeslib.as_array(r.point, shape=(n,)).copy(),
                "vertex": np.ctypeslib.as_array(r.vertex, shape=(nv,)).copy(),
                "point_scale": r.point_scale, "vertex_scale": r.vertex_scale}
    finally:
        lib.frep_distances_free(ctypes.byref(r))


def print_source(text, name="<string>", strict=False):
    """The canonical source of model text, as `frep print` prints it; strict: check
    every model first (frep print --strict).  Raises FrepError with the messages."""
    lib = _L()
    src = text.encode() if isinstance(text, str) else bytes(text)
    d = _Diagnostics(src)
    n = ctypes.c_size_t()
    p = lib.frep_print_source(name.encode(), src, len(src), 1 if strict else 0,
                              ctypes.byref(n), d.fn, None)
    if not p:
        d.fail("cannot print %s" % name)
    try:
        return ctypes.string_at(p, n.value).decode()
    finally:
        lib.frep_free(p)


# ---- meshes and clouds ---------------------------------------------------------------

class Mesh(_Wrapper):
    """An indexed triangle mesh: vertices (N, 3), normals (N, 3) or None, triangles
    (M, 3) uint32, counter-clockwise seen from outside.  The arrays are numpy views of
    the library's memory, valid as long as the Mesh lives."""

    def __init__(self, vertices, triangles, normals=None):
        v = np.ascontiguousarray(vertices, dtype=np.float64).reshape(-1, 3)
        t = np.ascontiguousarray(triangles, dtype=np.uint32).reshape(-1, 3)
        nr = None if normals is None else np.ascontiguousarray(normals, dtype=np.float64)
        if nr is not None and nr.shape != v.shape:
            raise ValueError("normals: one per vertex")
        d = _Diagnostics()
        h = _L().frep_mesh_new(v.shape[0], _ptr(v), _ptr(nr), t.shape[0], _ptr(t), d.fn, None)
        self._adopt(h, d, "cannot make the mesh")

    def _set(self, h):
        lib = _L()
        self._handle = _Handle(h, lib.frep_mesh_free)
        self._h = h
        self.info = None
        nv, nt = lib.frep_mesh_nverts(h), lib.frep_mesh_ntris(h)
        own = self._handle
        self.vertices = _view(lib.frep_mesh_vertices(h), (nv, 3), np.float64, own)
        self.triangles = _view(lib.frep_mesh_triangles(h), (nt, 3), np.uint32, own)
        nrm = lib.frep_mesh_normals(h)
        self.normals = _view(nrm, (nv, 3), np.float64, own) if nrm else None

    def write(self, path, fmt="auto", ascii=False):
        """Write STL, OBJ, PLY, OFF or VRML (from the extension unless fmt says), atomically."""
        d = _Diagnostics()
        if _L().frep_mesh_write(self._h, str(path).encode(), _MESH_FORMATS[fmt], int(ascii),
                                d.fn, None) != 0:
            d.fail("cannot write %s" % path)

    def check(self, self_intersections=False):
        """frep mesh --check's counts as a dict (a closed, oriented 2-manifold: all
        counts 0 and volume > 0)."""
        r = _MeshCheck()
        d = _Diagnostics()
        if _L().frep_mesh_check(self._h, int(self_intersections), ctypes.byref(r), d.fn,
                                None) != 0:
            d.fail("mesh check failed")
        out = {k: getattr(r, k) for k, _ in _MeshCheck._fields_}
        if not self_intersections:
            del out["self_intersections"]
        return out

    def sample(self, n, seed=1, noise=0.0, noise_absolute=False, outliers=0.0):
        """n area-weighted points on the triangles with the face normals: a Cloud."""
        lib = _L()
        o = _SampleOptions()
        lib.frep_sample_options_init(ctypes.byref(o))
        o.n, o.seed, o.noise = int(n), int(seed), float(noise)
        o.noise_absolute, o.outliers = int(bool(noise_absolute)), float(outliers)
        d = _Diagnostics()
        h = lib.frep_sample_mesh(self._h, ctypes.byref(o), d.fn, None)
        if not h:
            d.fail("sampling failed")
        return Cloud._own(h)

    def render(self, width=800, height=600, view="iso", points=None, program=None,
               scale=0.0, plain=False, iso=0.0, threads=0, colors=None):
        """A shaded picture, as frep render: an Image.  points: a Cloud drawn over the
        surface, coloured by its distance to program's surface f = iso (a Program) or,
        without one, to this mesh's triangles; the surface coloured by its distance to
        the points unless plain; scale: the distance drawn red (0: from the data).
        colors: (nverts, 3) uint8 vertex colours."""
        lib = _L()
        o = _RenderOptions()
        lib.frep_render_options_init(ctypes.byref(o))
        o.width, o.height, o.view = int(width), int(height), view.encode()
        o.scale, o.plain, o.iso, o.nthreads = float(scale), int(bool(plain)), float(iso), \
            int(threads)
        if points is not None:
            o.points = points._h
        if program is not None:
            o.program = program._h
        rgb = None
        if colors is not None:
            rgb = np.ascontiguousarray(colors, dtype=np.uint8).reshape(-1, 3)
            if rgb.shape[0] != self.vertices.shape[0]:
                raise ValueError("colors: one (r, g, b) per vertex")
            o.vertex_rgb = rgb.ctypes.data
        info = _RenderInfo()
        d = _Diagnostics()
        h = lib.frep_render(self._h, ctypes.byref(o), ctypes.byref(info), d.fn, None)
        if not h:
            d.fail("cannot render")
        return Image(h, {k: getattr(info, k) for k, _ in _RenderInfo._fields_})

    def to_open3d(self):
        """An open3d.geometry.TriangleMesh (copies), with vertex normals when known."""
        import open3d as o3d
        m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(self.vertices.copy()),
                                      o3d.utility.Vector3iVector(self.triangles.astype(np.int32)))
        if self.normals is not None:
            m.vertex_normals = o3d.utility.Vector3dVector(self.normals.copy())
        return m

    def to_trimesh_kwargs(self):
        """dict(vertices=..., faces=..., vertex_normals=...) for trimesh.Trimesh(**kw)."""
        kw = dict(vertices=self.vertices, faces=self.triangles)
        if self.normals is not None:
            kw["vertex_normals"] = self.normals
        return kw


class Cloud(_Wrapper):
    """Points with optional normals: x, y, z (and nx, ny, nz) are read-only numpy views
    of the library's structure-of-arrays cloud; points (N, 3) and normals (N, 3) or
    None are arrays gathered from them."""

    def __init__(self, points, normals=None):
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        cols = [np.ascontiguousarray(p[:, k]) for k in range(3)]
        ncols = [None] * 3
        if normals is not None:
            nr = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
            if nr.shape != p.shape:
                raise ValueError("normals: one per point")
            ncols = [np.ascontiguousarray(nr[:, k]) for k in range(3)]
        d = _Diagnostics()
        h = _L().frep_cloud_new(p.shape[0], *[_ptr(c) for c in cols + ncols], d.fn, None)
        self._adopt(h, d, "cannot make the cloud")

    def _set(self, h):
        self._handle = _Handle(h, _L().frep_cloud_free)
        self._h = h
        self._set_arrays()

    def _set_arrays(self):
        lib = _L()
        h = self._h
        n = lib.frep_cloud_size(h)
        ptrs = [_c_double_p() for _ in range(6)]
        lib.frep_cloud_arrays(h, *[ctypes.byref(p) for p in ptrs])
        cols = [_view(p, (n,), np.float64, self._handle) if p else None for p in ptrs]
        self.x, self.y, self.z = cols[:3]
        self.nx, self.ny, self.nz = cols[3:]
        self.points = np.stack(cols[:3], axis=1) if n else np.zeros((0, 3))
        self.normals = (np.stack(cols[3:], axis=1) if n else np.zeros((0, 3))) \
            if lib.frep_cloud_has_normals(h) else None

    def __len__(self):
        return self.points.shape[0]

    def write(self, path):
        """.xyz text or .ply binary (by the extension), atomically, as frep sample."""
        d = _Diagnostics()
        if _L().frep_cloud_write(self._h, str(path).encode(), d.fn, None) != 0:
            d.fail("cannot write %s" % path)

    def estimate_normals(self, knn=0, threads=0):
        """Estimate unit normals for every point in place, as frep normals (normals the
        cloud has are replaced): knn neighbours per plane fit (3..256; 0: chosen from
        the cloud's noise and spacing).  Returns what was found and used: a dict with
        knn, spacing, noise, components and flipped (parts turned outward)."""
        lib = _L()
        o = _NormalsOptions()
        lib.frep_normals_options_init(ctypes.byref(o))
        o.knn, o.nthreads = int(knn), int(threads)
        info = _NormalsInfo()
        d = _Diagnostics()
        rc = lib.frep_normals(self._h, ctypes.byref(o), ctypes.byref(info), d.fn, None)
        if rc != 0:
            d.fail("cannot estimate the normals")
        self._set_arrays()
        return {k: getattr(info, k) for k, _ in _NormalsInfo._fields_ if k != "interrupted"}

    def segment(self, seed=1, epsilon=0.0, types=None, separating=True, threads=0,
                progress=None, cancel=None, **kw):
        """Efficient RANSAC, as frep segment: a Segmentation.  types: names of
        PRIM_TYPES (None: all); kw: cluster, normal_deg, min_points, min_points_small,
        probability, knn.  progress(stage, done, total, nprims) and cancel() -> bool are
        called from this thread as detection goes; cancel returning True stops it with
        what was found.  Normals are estimated into this cloud when it has none."""
        lib = _L()
        o = _SegmentOptions()
        lib.frep_segment_options_init(ctypes.byref(o))
        o.seed, o.epsilon, o.separating, o.nthreads = int(seed), float(epsilon), \
            int(bool(separating)), int(threads)
        if types is not None:
            o.types = sum(1 << PRIM_TYPES.index(t) for t in types)
        for k, v in kw.items():
            if k not in ("cluster", "normal_deg", "min_points", "min_points_small",
                         "probability", "knn"):
                raise TypeError("segment: unknown option %r" % k)
            setattr(o, k, v)
        if progress is not None:
            o.progress = _SEG_PROGRESS_FN(
                lambda u, st, done, total, n: progress(st.decode(), done, total, n))
        if cancel is not None:
            o.cancel = _SEG_CANCEL_FN(lambda u: 1 if cancel() else 0)
        d = _Diagnostics()
        h = lib.frep_segment(self._h, ctypes.byref(o), d.fn, None)
        if not h:
            d.fail("segmentation failed")
        if lib.frep_cloud_has_normals(self._h) and self.normals is None:
            self._set_arrays()
        return Segmentation(h, lib.frep_cloud_size(self._h))

    def evolve(self, prims=None, progress=None, cancel=None, trace=None, base=None,
               **options):
        """A construction tree of primitives fitting this cloud, as frep evolve: an
        Evolution.  prims: a Segmentation (Cloud.segment, read_prims) or None (the cloud
        is segmented with frep segment's defaults).  options: seed (1), threads, setops
        ("minmax" or "rfunc"), generations, stagnation, population, tournament, elite,
        crossover, mutation, subtree_prob, max_depth, max_time (the whole run's
        seconds), partition, polish, polish_stagnation, simplify, support, sample,
        epsilon, alpha_deg (0: automatic), lambda_scale, knn, refit, report_explained,
        stop_share (percent).  progress(dict) and cancel() -> bool are called from this
        thread after each generation (dict["phase"] indexes EVOLVE_PHASES); cancel
        returning True stops the run with the best tree so far.  trace(line) gets the
        lines of frep evolve --trace.  base: an EvolveBase the tree is joined to (frep
        evolve --residual).  Normals are estimated into this cloud when it has none."""
        lib = _L()
        o = _EvolveOptions()
        lib.frep_evolve_options_init(ctypes.byref(o))
        fields = {k for k, _ in _EvolveOptions._fields_} - {"progress", "cancel", "user",
                                                            "cancel_flag", "trace", "base"}
        for k, v in options.items():
            if k == "threads":
                k = "nthreads"
            elif k == "setops":
                v = {"rfunc": 0, "minmax": 1}[v]
            elif k not in fields:
                raise TypeError("evolve: unknown option %r" % k)
            setattr(o, k, v)
        if progress is not None:
            o.progress = _EVOLVE_PROGRESS_FN(lambda u, p: progress(
                {k: getattr(p.contents, k) for k, _ in _EvolveProgress._fields_}))
        if cancel is not None:
            o.cancel = _SEG_CANCEL_FN(lambda u: 1 if cancel() else 0)
        if trace is not None:
            o.trace = _EVOLVE_TRACE_FN(lambda u, line: trace(line.decode()))
        if base is not None:
            o.base = base._h
        d = _Diagnostics()
        h = lib.frep_evolve(self._h, prims._h if prims is not None else None, ctypes.byref(o),
                            d.fn, None)
        if not h:
            d.fail("evolution failed")
        if lib.frep_cloud_has_normals(self._h) and self.normals is None:
            self._set_arrays()
        return Evolution(h, self, base)


class Segmentation:
    """The primitives frep segment finds: nprims (fitted first, then separating),
    nfitted, unassigned, interrupted, labels (per point: its fitted primitive or -1)."""

    def __init__(self, h, npoints):
        lib = _L()
        self._handle = _Handle(h, lib.frep_segmentation_free)
        self._h = h
        self.nprims = lib.frep_segmentation_nprims(h)
        self.nfitted = lib.frep_segmentation_nfitted(h)
        self.unassigned = lib.frep_segmentation_unassigned(h)
        self.interrupted = bool(lib.frep_segmentation_interrupted(h))
        self.labels = _view(lib.frep_segmentation_labels(h), (npoints,), np.int32, self._handle)
        info = _SegmentInfo()
        lib.frep_segmentation_get_info(h, ctypes.byref(info))
        self.info = {k: getattr(info, k) for k, _ in _SegmentInfo._fields_}
        self.info["normals_estimated"] = bool(self.info["normals_estimated"])
        self.info["interrupted"] = bool(self.info["interrupted"])

    def prims(self):
        """The primitives, fitted first: a list of dicts with type (a name of
        PRIM_TYPES), p, a (3-tuples), r, R, separating, support and rms, as
        frep.h's frep_prim describes them."""
        lib = _L()
        out = []
        for j in range(self.nprims):
            q = _Prim()
            lib.frep_segmentation_get_prim(self._h, j, ctypes.byref(q))
            out.append({"type": lib.frep_prim_type_name(q.type).decode(), "p": tuple(q.p),
                        "a": tuple(q.a), "r": q.r, "R": q.R,
                        "separating": bool(q.separating), "support": q.support,
                        "rms": q.rms})
        return out

    def write(self, path, header=None):
        """A .fit list (path ending in .fit) or a .hf model with header comment lines."""
        d = _Diagnostics()
        if _L().frep_segmentation_write(self._h, str(path).encode(),
                                        header.encode() if header else None, d.fn, None) != 0:
            d.fail("cannot write %s" % path)


def _view(ptr, shape, dtype, owner):
    """A numpy view of library memory owned by `owner` (kept alive through .base)."""
    n = int(np.prod(shape))
    if n == 0:
        return np.zeros(shape, dtype=dtype)
    a = np.ctypeslib.as_array(ptr, shape=(n,)).view(dtype).reshape(shape)
    a.flags.writeable = False
    return _Owned(a, owner)


class _Owned(np.ndarray):
    """An ndarray view that keeps the Python object owning its memory alive."""

    def __new__(cls, a, owner):
        obj = a.view(cls)
        obj._owner = owner
        return obj

    def __array_finalize__(self, obj):
        self._owner = getattr(obj, "_owner", None)


def normals(points, knn=0, threads=0, info=False):
    """Unit normals of the points ((N, 3) array-like), estimated as frep normals does:
    an (N, 3) float64 array (a new one; the points are copied into a cloud).  knn:
    neighbours per plane fit (3..256; 0: chosen from the noise and spacing); with
    info=True, returns (normals, dict of Cloud.estimate_normals)."""
    c = Cloud(points)
    found = c.estimate_normals(knn=knn, threads=threads)
    n = np.array(c.normals)
    return (n, found) if info else n


def read_cloud(path):
    """Read .xyz or PLY: a Cloud."""
    d = _Diagnostics()
    h = _L().frep_cloud_read(str(path).encode(), d.fn, None)
    if not h:
        d.fail("cannot read %s" % path)
    return Cloud._own(h)


def read_mesh(path):
    """Read OFF, OBJ, STL or PLY: a Mesh (normals None)."""
    d = _Diagnostics()
    h = _L().frep_mesh_read(str(path).encode(), d.fn, None)
    if not h:
        d.fail("cannot read %s" % path)
    return Mesh._own(h)


# ---- fitting -------------------------------------------------------------------------

class Fit:
    """A finished fit (frep fit): parameters, a list of dicts (name, index, start,
    value, lo, hi, sigma, sensitivity, warnings: names of FIT_WARNINGS); values, the
    template's whole parameter vector with the fitted values (as Program.eval takes
    it); params, {name: fitted value}; text, the fitted template; and the measures:
    npoints, objective, rms, max_dist, within, within_inliers, diagonal, noise,
    outliers, evals, seconds, converged, interrupted, status, verdict."""

    def __init__(self, h, name):
        lib = _L()
        self._handle = _Handle(h, lib.frep_fit_free)
        self._h = h
        self.name = name
        self.parameters = []
        for j in range(lib.frep_fit_nparams(h)):
            r = _FitParam()
            lib.frep_fit_get_param(h, j, ctypes.byref(r))
            self.parameters.append(dict(
                name=r.name.decode(), index=r.index, start=r.start, value=r.value, lo=r.lo,
                hi=r.hi, sigma=r.sigma, sensitivity=r.sensitivity,
                warnings=[w for k, w in enumerate(FIT_WARNINGS) if r.warnings & (1 << k)]))
        self.params = {p["name"]: p["value"] for p in self.parameters}
        n = lib.frep_fit_nvalues(h)
        self.values = np.zeros(n)
        lib.frep_fit_values(h, _ptr(self.values), n)
        ln = ctypes.c_size_t()
        t = lib.frep_fit_text(h, ctypes.byref(ln))
        self.text = ctypes.string_at(t, ln.value).decode(errors="replace")
        info = _FitInfo()
        lib.frep_fit_get_info(h, ctypes.byref(info))
        for k, _ in _FitInfo._fields_:
            v = getattr(info, k)
            setattr(self, k, v.decode() if isinstance(v, bytes) else v)
        self.converged, self.interrupted = bool(self.converged), bool(self.interrupted)

    def write(self, path):
        """Write the fitted template (as frep fit -o path), atomically."""
        d = _Diagnostics()
        if _L().frep_fit_write(self._h, str(path).encode(), d.fn, None) != 0:
            d.fail("cannot write %s" % path)

    def write_json(self, path, template_name=None, cloud_name=None, output_name=None):
        """Write the report as frep fit --json does, quoting the names given."""
        d = _Diagnostics()
        enc = [str(x).encode() if x is not None else None
               for x in (template_name, cloud_name, output_name)]
        if _L().frep_fit_write_json(self._h, str(path).encode(), *enc, d.fn, None) != 0:
            d.fail("cannot write %s" % path)

    def program(self, **kw):
        """The fitted template compiled (keyword arguments as compile's)."""
        return compile(self.text, name=self.name, **kw)


def fit(template, cloud, name="<string>", model=None, a=None, strict=False, bounds=None,
        progress=None, cancel=None, **options):
    """Fit the free parameters of the template source text to a Cloud (or an (N, 3)
    array of points), as frep fit: the '-- @free' parameters, else the elements of a[]
    the model reads, started from `a` and bounded by `bounds` (a list of (lo, hi), one
    per element of a[]).  options: seed (1), method (FIT_METHODS, "saqn"), objective
    and global_objective (FIT_OBJECTIVES), loss and sa_loss (FIT_LOSSES), loss_scale,
    robust, normals_weight, max_time, max_evals, sa_points, sa_stall, sa_chains,
    sa_threshold, threads.  progress(dict) and cancel() -> bool are called from this
    thread (at most every 0.2 s); cancel returning True stops the fit with the best
    parameters so far.  Returns a Fit; raises FrepError with the messages."""
    lib = _L()
    if not isinstance(cloud, Cloud):
        cloud = Cloud(cloud)
    src = template.encode() if isinstance(template, str) else bytes(template)
    co, keep = _compile_options(model, a, None, True, strict)
    o = _FitOptions()
    lib.frep_fit_options_init(ctypes.byref(o))
    names = {"method": FIT_METHODS, "objective": FIT_OBJECTIVES,
             "global_objective": FIT_OBJECTIVES, "loss": FIT_LOSSES, "sa_loss": FIT_LOSSES}
    for k, v in options.items():
        if k in names:
            if v not in names[k]:
                raise ValueError("fit: %s must be one of %s" % (k, ", ".join(names[k])))
            v = names[k].index(v)
        elif k == "threads":
            k = "nthreads"
        elif k == "robust":
            v = int(bool(v))
        elif k not in ("seed", "loss_scale", "normals_weight", "max_time", "max_evals",
                       "sa_points", "sa_stall", "sa_chains", "sa_threshold"):
            raise TypeError("fit: unknown option %r" % k)
        setattr(o, k, v)
    if bounds is not None:
        b = np.asarray(bounds, dtype=np.float64).reshape(-1, 2)
        lo, hi = np.ascontiguousarray(b[:, 0]), np.ascontiguousarray(b[:, 1])
        keep += [lo, hi]
        o.lo = ctypes.cast(_ptr(lo), _c_double_p)
        o.hi = ctypes.cast(_ptr(hi), _c_double_p)
        o.nbounds = b.shape[0]
    if progress is not None:
        o.progress = _FIT_PROGRESS_FN(lambda u, p: progress(
            {k: getattr(p.contents, k) for k, _ in _FitProgress._fields_}))
    if cancel is not None:
        o.cancel = _SEG_CANCEL_FN(lambda u: 1 if cancel() else 0)
    d = _Diagnostics(src)
    h = lib.frep_fit_template(name.encode(), src, len(src), ctypes.byref(co), cloud._h,
                              ctypes.byref(o), d.fn, None)
    if not h:
        d.fail("cannot fit %s" % name)
    if lib.frep_cloud_has_normals(cloud._h):
        cloud._set_arrays()
    return Fit(h, name)


def fit_file(path, cloud, **kw):
    """Fit the template file at path (see fit)."""
    with open(path, "rb") as f:
        return fit(f.read(), cloud, name=kw.pop("name", str(path)), **kw)


# ---- construction trees --------------------------------------------------------------

def read_prims(path):
    """Primitives from a .fit list or a .hf model of frep segment (frep evolve -p): a
    Segmentation without labels."""
    d = _Diagnostics()
    h = _L().frep_segmentation_read(str(path).encode(), d.fn, None)
    if not h:
        d.fail("cannot read %s" % path)
    return Segmentation(h, 0)


class Evolution:
    """An evolved construction tree (Cloud.evolve): tree_size, nprims, npoints,
    dropped, explained, within_eps, normals_ok, fitness, generations, seconds,
    alpha_deg, alpha_auto, partitioned, interrupted, refit_rms_before/after."""

    def __init__(self, h, cloud, base=None):
        lib = _L()
        self._handle = _Handle(h, lib.frep_evolution_free)
        self._h = h
        self._cloud = cloud          # the library reads it when writing
        self._base = base            # and the base's source
        info = _EvolveInfo()
        lib.frep_evolution_get_info(h, ctypes.byref(info))
        for k, _ in _EvolveInfo._fields_:
            setattr(self, k, getattr(info, k))
        for k in ("alpha_auto", "partitioned", "interrupted"):
            setattr(self, k, bool(getattr(self, k)))

    def write(self, path, command=None, cloud_name=None, exact=False, hyperfun=False):
        """Write the .hf model as frep evolve -o does (command and cloud_name go into its
        comments; exact, hyperfun as --exact-numbers, --hyperfun)."""
        d = _Diagnostics()
        enc = [str(x).encode() if x is not None else None for x in (command, cloud_name)]
        if _L().frep_evolution_write(self._h, str(path).encode(), *enc, int(bool(exact)),
                                     int(bool(hyperfun)), d.fn, None) != 0:
            d.fail("cannot write %s" % path)

    def write_dot(self, path):
        """Write the tree for Graphviz (frep evolve --dot)."""
        d = _Diagnostics()
        if _L().frep_evolution_write_dot(self._h, str(path).encode(), d.fn, None) != 0:
            d.fail("cannot write %s" % path)

    def model(self, command=None, cloud_name=None, exact=False, hyperfun=False):
        """The .hf model write() writes, as a string."""
        d = _Diagnostics()
        n = ctypes.c_size_t()
        enc = [str(x).encode() if x is not None else None for x in (command, cloud_name)]
        p = _L().frep_evolution_model(self._h, *enc, int(bool(exact)), int(bool(hyperfun)),
                                      ctypes.byref(n), d.fn, None)
        return _take_text(p, n, d)

    def dot(self):
        """The Graphviz drawing write_dot() writes, as a string."""
        d = _Diagnostics()
        n = ctypes.c_size_t()
        return _take_text(_L().frep_evolution_dot(self._h, ctypes.byref(n), d.fn, None), n, d)


def _take_text(p, n, d):
    """A string the library allocated (freed here)."""
    if not p:
        d.fail("out of memory")
    text = ctypes.string_at(p, n.value).decode()
    _L().frep_free(p)
    return text


class EvolveBase:
    """A model an evolved tree is joined to (frep evolve --residual MODEL): program, a
    Program from compile or compile_file (model: the model it compiled, None: the
    default).  setops: the family the joined tree uses."""

    def __init__(self, program, model=None):
        lib = _L()
        d = _Diagnostics(program.source)
        h = lib.frep_evolve_base_new(program._h, program.name.encode(), program.source,
                                     len(program.source),
                                     model.encode() if model else None, d.fn, None)
        if not h:
            d.fail("cannot join to %s" % program.name)
        self._handle = _Handle(h, lib.frep_evolve_base_free)
        self._h = h
        self._program = program      # the base reads it
        self.setops = ("rfunc", "minmax")[lib.frep_evolve_base_setops(h)]


class Image:
    """A picture of Mesh.render: pixels, a (height, width, 3) uint8 view of the
    library's memory; info, what it shows (ntris, npoints, mean_dist, max_dist,
    inside, rings, point_scale, surface_scale)."""

    def __init__(self, h, info):
        lib = _L()
        self._handle = _Handle(h, lib.frep_image_free)
        self._h = h
        self.info = info
        w, ht = ctypes.c_int(), ctypes.c_int()
        px = lib.frep_image_pixels(h, ctypes.byref(w), ctypes.byref(ht))
        self.pixels = _view(px, (ht.value, w.value, 3), np.uint8, self._handle)

    def write_png(self, path):
        """Write as PNG (as frep render -o), atomically."""
        d = _Diagnostics()
        if _L().frep_image_write_png(self._h, str(path).encode(), d.fn, None) != 0:
            d.fail("cannot write %s" % path)
