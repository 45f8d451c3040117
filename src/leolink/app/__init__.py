"""The application layer: from a validated config to scenarios, runs, reports and files."""
