"""pushbot package."""
