# snapwarn: the REST API, its job worker and the dask scheduler/workers of atlases (one image,
# four commands; see docker-compose.yml and docs/atlas.md).
FROM python:3.11-slim AS base

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    MPLBACKEND=Agg \
    NUMBA_CACHE_DIR=/tmp/numba-cache

WORKDIR /app
COPY pyproject.toml README.md ./
COPY sim ./sim
COPY service ./service
COPY openapi ./openapi
RUN pip install --upgrade pip && pip install ".[postgres]" \
    && useradd --create-home --uid 10001 snapwarn \
    && mkdir -p /app/var && chown snapwarn /app/var

USER snapwarn
EXPOSE 8000
ENV SNAPWARN_HOST=0.0.0.0 SNAPWARN_PORT=8000
HEALTHCHECK --interval=10s --timeout=5s --start-period=30s --retries=3 \
    CMD python -c "import os, sys, urllib.request; u = 'http://127.0.0.1:%s/healthz' % os.environ.get('SNAPWARN_PORT', '8000'); sys.exit(0 if urllib.request.urlopen(u, timeout=4).status == 200 else 1)"
CMD ["snapwarn", "serve"]
