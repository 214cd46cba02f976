"""A pipe given by its drawing (issue 34, item 7): outer and inner diameter (or wall
thickness) [m], the wall's and the fluid's density [kg/m^3] or their names in
:mod:`pipeflow.materials`, replaced by the explicit ``E``, ``I``, ``M1``, ``M2`` of
:class:`pipeflow.schema.simulation.PipeSpec` before anything else is checked."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from pipeflow import materials
from pipeflow.errors import InvalidField
from pipeflow.schema import messages

#: the names of the table's materials and fluids (pipeflow.materials)
MaterialName = Literal["steel", "stainless", "aluminium", "copper", "PVC", "HDPE"]
FluidName = Literal["water", "sea water", "air", "oil"]


class PipeDrawing(BaseModel):
    """The pipe as drawn (issue 34, item 7): diameters, densities and names from the
    materials table (:mod:`pipeflow.materials`), instead of ``I``, ``M1``, ``M2`` (and
    ``E``).  :class:`PipeSpec` takes these fields and replaces them by the explicit ones
    before anything else is checked, so a pipe given by its drawing is the explicit
    request (same canonical form, same cache key).  Validated from converted SI numbers
    (:func:`pipeflow.schema.units.convert_fields` runs first), so the settings of the
    request models without their unit and cost hooks."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)

    outer_diameter: float | None = Field(
        None,
        gt=0,
        le=100.0,
        exclude=True,
        repr=False,
        description="Outer diameter D of the pipe [m]; with inner_diameter or wall_thickness "
        "it replaces I = pi (D^4 - d^4) / 64 [m^4].",
    )
    inner_diameter: float | None = Field(
        None,
        ge=0,
        le=100.0,
        exclude=True,
        repr=False,
        description="Inner (bore) diameter d [m], less than outer_diameter; or give "
        "wall_thickness. The flow area is pi d^2 / 4 [m^2].",
    )
    wall_thickness: float | None = Field(
        None,
        gt=0,
        le=50.0,
        exclude=True,
        repr=False,
        description="Wall thickness t [m], at most outer_diameter / 2 (d = D - 2 t); "
        "instead of inner_diameter.",
    )
    density: float | None = Field(
        None,
        gt=0,
        le=1e5,
        exclude=True,
        repr=False,
        description="Density rho_p of the pipe wall [kg/m^3]; with the diameters it "
        "replaces M1 = rho_p pi (D^2 - d^2) / 4 [kg/m]. Default: the material's.",
    )
    fluid_density: float | None = Field(
        None,
        ge=0,
        le=1e5,
        exclude=True,
        repr=False,
        description="Density rho_f of the conveyed fluid [kg/m^3]; with the inner diameter "
        "it replaces M2 = rho_f pi d^2 / 4 [kg/m]. Default: the fluid's.",
    )
    material: MaterialName | None = Field(
        None,
        exclude=True,
        repr=False,
        description="The wall's material from pipeflow's table (room-temperature handbook "
        "values, SI): its Young's modulus is the default of E and its density the default "
        "of density; either may be given too, overriding it.",
    )
    fluid: FluidName | None = Field(
        None,
        exclude=True,
        repr=False,
        description="The conveyed fluid from pipeflow's table: its density is the default "
        "of fluid_density.",
    )


#: the fields of the drawing form (PipeDrawing)
DRAWING_FIELDS = tuple(PipeDrawing.model_fields)


def drawing_field(name: str) -> Any:
    """The field ``name`` of :class:`PipeDrawing`, declared again on :class:`PipeSpec`."""
    return PipeDrawing.model_fields[name]


def from_drawing(data: dict[str, Any]) -> dict[str, Any]:
    """``data`` (a ``pipe`` request object) with its drawing fields (:class:`PipeDrawing`)
    replaced by ``I``, ``M1``, ``M2`` and ``E``; unchanged if it has none.  Refuses, naming
    the fields, a quantity given both ways (``I`` and the diameters, ``M1`` and
    ``density``, ``M2`` and ``fluid_density``) or a drawing that is incomplete."""
    given = {k: data[k] for k in DRAWING_FIELDS if k in data and data[k] is not None}
    if not given:
        return {k: v for k, v in data.items() if k not in DRAWING_FIELDS}
    for name, table in (("material", materials.MATERIALS), ("fluid", materials.FLUIDS)):
        value = given.get(name)
        if isinstance(value, str) and value not in table:
            raise InvalidField(
                f"{name}: unknown {name} {value!r}"
                + (
                    messages.did_you_mean(value, tuple(table))
                    or f"; choose one of {', '.join(repr(n) for n in table)}"
                ),
                name,
            )
    try:
        drawing = PipeDrawing.model_validate(given)
    except ValidationError as exc:
        err = exc.errors()[0]
        cause = (err.get("ctx") or {}).get("error")
        if isinstance(cause, InvalidField):
            raise InvalidField(cause.message, cause.loc) from None
        loc = ".".join(str(p) for p in err["loc"])
        raise InvalidField(f"{loc}: {messages.message(err)}", loc) from None
    out = {k: v for k, v in data.items() if k not in DRAWING_FIELDS}

    def clash(explicit: str, derived: str) -> None:
        if explicit in out:
            raise InvalidField(
                f"{explicit} and {derived} both given: give the pipe either explicitly "
                f"({explicit}) or by its drawing ({derived}), not both",
                explicit,
            )

    material = materials.MATERIALS[drawing.material] if drawing.material else None
    fluid = materials.FLUIDS[drawing.fluid] if drawing.fluid else None
    if material is not None and "E" not in out:
        out["E"] = material.E
    D, d, t = drawing.outer_diameter, drawing.inner_diameter, drawing.wall_thickness
    if d is not None and t is not None:
        raise InvalidField(
            "inner_diameter and wall_thickness both given: give one of them", "wall_thickness"
        )
    if (d is not None or t is not None) and D is None:
        raise InvalidField(
            f"{'inner_diameter' if d is not None else 'wall_thickness'} needs outer_diameter",
            "outer_diameter",
        )
    if D is not None:
        if d is None and t is None:
            raise InvalidField(
                "outer_diameter needs inner_diameter or wall_thickness", "inner_diameter"
            )
        if t is not None:
            if 2 * t > D:
                raise InvalidField(
                    f"wall_thickness = {t:g} m is more than outer_diameter / 2 = {D / 2:g} m",
                    "wall_thickness",
                )
            d = max(D - 2 * t, 0.0)
        assert d is not None
        if d >= D:
            raise InvalidField(
                f"inner_diameter = {d:g} m is not less than outer_diameter = {D:g} m",
                "inner_diameter",
            )
        clash("I", "outer_diameter")
        section = materials.Section(D, d)
        out["I"] = section.I
        rho_p = (
            drawing.density
            if drawing.density is not None
            else (material.density if material is not None else None)
        )
        if rho_p is not None:
            clash("M1", "density" if drawing.density is not None else "material")
            out["M1"] = rho_p * section.wall_area
        rho_f = (
            drawing.fluid_density
            if drawing.fluid_density is not None
            else (fluid.density if fluid is not None else None)
        )
        if rho_f is not None:
            clash("M2", "fluid_density" if drawing.fluid_density is not None else "fluid")
            out["M2"] = rho_f * section.flow_area
    else:
        for name in ("density", "fluid_density", "fluid"):
            if name in given:
                raise InvalidField(
                    f"{name} needs outer_diameter and inner_diameter (or wall_thickness)", name
                )
    for name, derived in (("M1", "density or material"), ("M2", "fluid_density or fluid")):
        if name not in out and D is not None:
            raise InvalidField(f"{name}: give {name} [kg/m] or {derived}", name)
    return out
