"""The crossdyn report and scene pictures (run through reports/make_report.py and
reports/draw_scene.py with Debian's /usr/bin/python3, which has matplotlib and Jinja2)."""
