# snapwarn: the REST API, its job worker and the dask scheduler/workers of atlases (one image,
# four commands; see docker-compose.yml and docs/atlas.md).
FROM python:3.11-slim AS base

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    MPLBACKEND=Agg \
    NUMBA_CACHE_DIR=/app/numba-cache

WORKDIR /app
COPY pyproject.toml README.md ./
COPY sim ./sim
COPY service ./service
COPY openapi ./openapi
RUN pip install --upgrade pip && pip install ".[postgres]" \
    && rm -rf /app/sim /app/service \
    && useradd --create-home --uid 10001 snapwarn \
    && mkdir -p /app/var && chown snapwarn /app/var

# numba's kernels compiled once, here, into the image (as `make setup` does for a checkout):
# the first request of a container is served warm. (The sources were copied only to be
# installed and are removed above: the kernels compiled are those of site-packages, the code
# every command of the image runs; numba's cache is keyed by the source file's path.) numba keys its cache by the CPU the code is
# compiled for; "generic" code runs (and hits the cache) on any x86-64 host, without the newer
# vector instructions. An image built for one known host type may name it instead
# (`--build-arg NUMBA_CPU_NAME=skylake-avx512`): on another CPU it then compiles at start.
ARG NUMBA_CPU_NAME=generic
ENV NUMBA_CPU_NAME=${NUMBA_CPU_NAME}
RUN mkdir -p /app/numba-cache && python -m service.warmup && python -m service.warmup --check \
    && chown -R snapwarn /app/numba-cache

USER snapwarn
EXPOSE 8000
ENV SNAPWARN_HOST=0.0.0.0 SNAPWARN_PORT=8000
HEALTHCHECK --interval=10s --timeout=5s --start-period=30s --retries=3 \
    CMD python -c "import json, os, sys, urllib.request; u = 'http://127.0.0.1:%s/healthz' % os.environ.get('SNAPWARN_PORT', '8000'); r = urllib.request.urlopen(u, timeout=4); sys.exit(0 if r.status == 200 and json.load(r).get('ready', True) else 1)"
CMD ["snapwarn", "serve"]
