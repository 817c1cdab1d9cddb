"""Developer tools: ensure_browser (Chromium for the viewer tests), report_stats."""
