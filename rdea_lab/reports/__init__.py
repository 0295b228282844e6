"""Reports: tables and figures that compare models and measurements."""
