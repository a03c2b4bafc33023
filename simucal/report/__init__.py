"""What the runtime shows a user: markdown tables, the HTML diagnosis, and dong2018's
numeric claims against a Monte Carlo."""
