"""Request models of the distributions a sampled design study draws from (re-exported by
:mod:`pipeflow.schema.study`, where they were defined before); each model's
:meth:`to_distribution` gives the library's (:mod:`pipeflow.uq`), which maps probabilities to
values by its inverse CDF."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from pipeflow import uq
from pipeflow.schema.base import StrictModel


class NormalDistribution(StrictModel):
    """A normal distribution N(mean, std^2)."""

    distribution: Literal["normal"] = Field(description="Normal: mean and std.")
    mean: float = Field(description="Mean, in the field's own SI unit.")
    std: float = Field(description="Standard deviation (> 0), in the field's own SI unit.")

    def to_distribution(self) -> uq.Normal:
        """The library's distribution (:mod:`pipeflow.uq`)."""
        return uq.Normal(self.mean, self.std)


class TruncatedNormalDistribution(StrictModel):
    """A normal distribution N(mean, std^2) restricted to [low, high] (renormalised)."""

    distribution: Literal["truncated_normal"] = Field(
        description="Truncated normal: the normal of mean and std restricted to [low, high]."
    )
    mean: float = Field(description="Mean of the untruncated normal, in the field's SI unit.")
    std: float = Field(description="Its standard deviation (> 0), in the field's SI unit.")
    low: float = Field(description="Lower end (< high), in the field's SI unit.")
    high: float = Field(description="Upper end, in the field's SI unit.")

    def to_distribution(self) -> uq.TruncatedNormal:
        """The library's distribution (:mod:`pipeflow.uq`)."""
        return uq.TruncatedNormal(self.mean, self.std, self.low, self.high)


class UniformDistribution(StrictModel):
    """A uniform distribution on [low, high]."""

    distribution: Literal["uniform"] = Field(description="Uniform on [low, high].")
    low: float = Field(description="Lower end (< high), in the field's own SI unit.")
    high: float = Field(description="Upper end, in the field's own SI unit.")

    def to_distribution(self) -> uq.Uniform:
        """The library's distribution (:mod:`pipeflow.uq`)."""
        return uq.Uniform(self.low, self.high)


class LognormalDistribution(StrictModel):
    """A lognormal distribution: ln X ~ N(ln median, sigma^2)."""

    distribution: Literal["lognormal"] = Field(
        description="Lognormal: ln X normal with mean ln(median) and standard deviation sigma."
    )
    median: float = Field(description="Median (> 0), in the field's own SI unit.")
    sigma: float = Field(description="Standard deviation of ln X (> 0) [-].")

    def to_distribution(self) -> uq.Lognormal:
        """The library's distribution (:mod:`pipeflow.uq`)."""
        return uq.Lognormal(self.median, self.sigma)


Distribution = Annotated[
    NormalDistribution | TruncatedNormalDistribution | UniformDistribution | LognormalDistribution,
    Field(discriminator="distribution"),
]
#: the distributions a sampled study draws from, by name
DISTRIBUTIONS = ("normal", "truncated_normal", "uniform", "lognormal")
