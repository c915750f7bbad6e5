"""The core: the appraisal, the emotions (Table II), the behaviour table (Table III), each agent's settings, the
registry of agent names and the episode log. Importable without torch, numba or pandas."""
