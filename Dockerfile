# fleetpinn service: CPU torch, migrations at start, uvicorn.
#   docker build -t fleetpinn .
#   docker run -p 8000:8000 -v fleetpinn-data:/data fleetpinn
# The database defaults to a SQLite file on the /data volume; point FLEETPINN_DATABASE_URL at
# PostgreSQL (postgresql+psycopg://...) to share it between containers.
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    OMP_NUM_THREADS=1 \
    NUMBA_CACHE_DIR=/srv/numba-cache \
    FLEETPINN_DATABASE_URL=sqlite:////data/fleetpinn.db

WORKDIR /srv/fleetpinn

# The CPU wheel first, pinned, so resolving the project never pulls a CUDA build.
RUN pip install torch==2.13.0 --index-url https://download.pytorch.org/whl/cpu

COPY pyproject.toml README.md alembic.ini ./
COPY model ./model
COPY app ./app
COPY migrations ./migrations
RUN pip install ".[postgres]"

RUN useradd --create-home --uid 10001 fleetpinn \
    && mkdir -p /data /srv/numba-cache \
    && chown fleetpinn /data /srv/numba-cache
USER fleetpinn
# Compile every loop a retrain or forecast runs into numba's cache now (model.compile_ahead),
# so the first retrain or forecast does not wait.
RUN python -c "from model.runtime import warm_up; warm_up()"
VOLUME ["/data"]
EXPOSE 8000

HEALTHCHECK --interval=30s --timeout=5s --start-period=60s \
    CMD python -c "import urllib.request; urllib.request.urlopen('http://127.0.0.1:8000/ready')"

# `serve` applies the migrations (alembic upgrade head), then runs uvicorn.
CMD ["fleetpinn", "serve", "--host", "0.0.0.0", "--port", "8000"]
