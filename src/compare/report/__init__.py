"""Static HTML report: pages, plots, image encoding, headless-browser check."""
