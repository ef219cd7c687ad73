"""What is solved: the ElasticityProblem (spaces, the energy sum, loads, Dirichlet data) and the terms
that tie it to bones and obstacles (model.problem.bones, model.problem.contact)."""

from model.problem.elasticity import DirichletBoundary, ElasticityProblem

__all__ = ["DirichletBoundary", "ElasticityProblem"]
