"""The papers' experiments as declarative suites of run configs, with their table builders."""
