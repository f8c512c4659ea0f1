"""The force-model registry (issue 30 item 3): one model per cutter class behind one protocol."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.config import EndMillCoefficients, FaceMillCoefficients, get_tool, load_tools
from analysis.errors import AnalysisError
from analysis.forces import (
    ENDMILL,
    FACEMILL,
    MODELS,
    EndMillCut,
    ForceModel,
    model_for,
    model_named,
)
from analysis.identify import RunConditions


def test_every_catalogue_tool_has_exactly_one_model() -> None:
    for name, tool in load_tools().items():
        model = model_for(tool)
        assert isinstance(model, ForceModel), name
        assert [m.name for m in MODELS.values() if m.describes(tool)] == [model.name], name
        # the catalogue schema of the model is the tool's own
        assert isinstance(tool, model.tool_schema), name
        assert model.teeth(tool) >= 1


def test_unknown_tools_and_models_are_refused_in_one_line() -> None:
    with pytest.raises(AnalysisError, match="no force model describes it"):
        model_for(object())
    with pytest.raises(AnalysisError, match="model 'drill': expected one of facemill, endmill"):
        model_named("drill")


def test_identification_design_needs_three_feeds_for_edge_terms() -> None:
    assert FACEMILL.identifiable([0.236, 0.236]) == ("K_T_n_mm2", "K_R", "K_A")
    assert ENDMILL.identifiable([0.05, 0.1]) == ("Ktc_n_mm2", "Krc_n_mm2", "Kac_n_mm2")
    full = ENDMILL.identifiable([0.05, 0.1, 0.15])
    assert set(ENDMILL.edge_keys) <= set(full)
    # every key the design names is a field of the material's table of that model
    for m in MODELS.values():
        assert set(m.identifiable([1, 2, 3])) == set(m.coefficients_schema.model_fields)


def test_a_slot_mean_force_closed_form_through_the_protocol() -> None:
    """Altintas' slot mean force of a flat end mill: Fx = N a Kte / pi ... independent of the
    model code: F_y (cross-feed, workpiece) = N a (Ktc fz / 4) (a slot, no edge)."""
    tool = get_tool("phi10-flat")
    coef = EndMillCoefficients(Ktc_n_mm2=800, Krc_n_mm2=0, Kac_n_mm2=0, Kte_n_mm=0, Kre_n_mm=0,
                               Kae_n_mm=0)  # fmt: skip
    c = RunConditions(spindle_rpm=6000, fz_mm=0.1, depth_mm=2.0, mode="slot")
    model = model_for(tool)
    mean = model.mean_design(tool, model.cut(tool, c)) @ model.coefficient_vector(coef)
    n = tool.flutes
    # mean over a revolution of the tangential force on the workpiece, projected: N a Ktc fz / 4
    assert abs(abs(mean[1]) - n * 2.0 * 800 * 0.1 / 4) < 1e-6 * 800
    phi = np.linspace(0, 2 * np.pi, 3600, endpoint=False)
    f = model.forces(phi, tool, coef, EndMillCut(0.1, 2.0, 0.0, 180.0))
    assert np.allclose(f.mean(axis=0)[:2], mean[:2], atol=0.5)


def test_face_mill_cut_needs_the_width() -> None:
    c = RunConditions(spindle_rpm=600, fz_mm=0.2, depth_mm=2.0)
    with pytest.raises(AnalysisError, match="width_mm = nan: face-mill runs need"):
        FACEMILL.cut(get_tool("seed003-facemill"), c)
    assert FACEMILL.coefficients_schema is FaceMillCoefficients
