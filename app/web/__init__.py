"""What people see: server-rendered pages, charts and the offline API docs' assets.

Templates (templates/) and the stylesheet (static/) ship inside the package; nothing is loaded
from a CDN and there is no JavaScript build step.  Forecast data is read through one adapter
(app.web.source), so the pages follow the services wherever they move.
"""
