# syntax=docker/dockerfile:1
# voxd: the HTTP voxelization service in a container.
#
#   docker build -t voxd .
#   docker run --rm -p 8080:8080 voxd                       # CPU engine (lavapipe with -e VOXD_ENGINE=gpu)
#   docker run --rm -p 8080:8080 --runtime=nvidia --gpus all \
#       -e NVIDIA_DRIVER_CAPABILITIES=graphics,compute,utility -e VOXD_ENGINE=gpu \
#       -e VK_DRIVER_FILES=/usr/share/voxd/nvidia_egl_icd.json voxd
#
# Configuration comes only from VOXD_* and AWS_* variables (README, "Command line" and
# "Replicas"). The NVIDIA container toolkit mounts the host's driver at run time; none is baked
# in here. Its Vulkan ICD file names the GLX library, which finds no device headless: the GPU
# overlays point VK_DRIVER_FILES at /usr/share/voxd/nvidia_egl_icd.json (the EGL library) instead.
#
# The binary comes from the build stage (Rust, from source) unless VOXD_BIN_STAGE=prebuilt: then
# it is the file `voxd` at the root of the build context, a binary built outside for Debian 12
# (glibc 2.36), and the Rust stage is skipped. scripts/image-check.sh builds the image that way
# (crates cannot be fetched from inside a build there):
#   podman build --format docker --build-arg VOXD_BIN_STAGE=prebuilt -f Dockerfile DIR_WITH_VOXD

# Which stage supplies /out/voxd: build (the default) or prebuilt. A stage chosen through FROM,
# not through COPY --from=${...}: buildah resolves --from before it expands variables.
ARG VOXD_BIN_STAGE=build

############################## build ##############################
FROM rust:1.95-bookworm AS build
WORKDIR /src

# Dependencies in their own layer: the manifest and lock file with stub targets, built once and
# reused for as long as Cargo.toml and Cargo.lock do not change.
COPY Cargo.toml Cargo.lock ./
RUN mkdir -p src tests \
 && echo 'fn main() {}' > src/main.rs \
 && : > src/lib.rs \
 && : > tests/tests.rs \
 && cargo build --release --locked --bin voxd \
 && rm -rf src target/release/voxd target/release/deps/voxd-* target/release/deps/libvoxd-* \
           target/release/.fingerprint/voxd-*

# The real source (the shaders and Lua scripts are compiled in with include_str!). The empty
# tests/tests.rs stays: Cargo.toml names it as a target, and tests/ is not in the context.
COPY src ./src
COPY shaders ./shaders
RUN cargo build --release --locked --bin voxd \
 && install -D -m 0755 target/release/voxd /out/voxd

############################## prebuilt ##############################
# Only with --build-arg VOXD_BIN_STAGE=prebuilt (BuildKit and buildah skip unused stages).
FROM scratch AS prebuilt
COPY --chmod=0755 voxd /out/voxd

FROM ${VOXD_BIN_STAGE} AS bin

############################## runtime ##############################
FROM debian:bookworm-slim

# mesa-vulkan-drivers: lavapipe (Vulkan on the CPU) where no GPU is passed in; libvulkan1: the
# Vulkan loader; libegl1 + libxext6: what the NVIDIA driver's Vulkan ICD, mounted by the NVIDIA
# container toolkit, links against; tini: PID 1 that forwards SIGTERM to voxd (graceful
# shutdown) and reaps children; curl: only for the HEALTHCHECK (voxd has no health
# subcommand); ca-certificates: TLS to S3.
# Versions are not pinned: bookworm's security updates replace them, and a pinned version
# disappears from the mirror as soon as one lands, which breaks the build; the base image tag
# fixes the release.
# hadolint ignore=DL3008
RUN apt-get update \
 && apt-get install -y --no-install-recommends \
        mesa-vulkan-drivers libvulkan1 libegl1 libxext6 ca-certificates tini curl \
 && rm -rf /var/lib/apt/lists/*

# A fixed, unprivileged uid/gid, so that volumes and Kubernetes' runAsUser can name it.
# And an ICD file for NVIDIA's driver through its EGL library, for the GPU overlays'
# VK_DRIVER_FILES: the toolkit's own nvidia_icd.json names libGLX_nvidia.so.0, which finds no
# device in a headless container (measured on an H200, docs/benchmarks-history.md 2026-12-04).
RUN groupadd --system --gid 10001 voxd \
 && useradd --system --uid 10001 --gid voxd --home-dir /data --no-create-home --shell /usr/sbin/nologin voxd \
 && mkdir -p /data /usr/share/voxd \
 && chown voxd:voxd /data \
 && printf '{"file_format_version":"1.0.1","ICD":{"library_path":"libEGL_nvidia.so.0","api_version":"1.3.0"}}\n' \
        > /usr/share/voxd/nvidia_egl_icd.json

COPY --from=bin /out/voxd /usr/local/bin/voxd

# The default 127.0.0.1 is unreachable from outside the container. /data holds volumes and job
# records unless VOXD_STORE=s3://… puts them in a bucket. Logs: one JSON object per line, for
# the container runtime's log shipper (VOXD_LOG_FORMAT=text for people).
ENV VOXD_ADDR=0.0.0.0:8080 \
    VOXD_DATA_DIR=/data \
    VOXD_LOG=info \
    VOXD_LOG_FORMAT=json

USER 10001:10001
VOLUME ["/data"]
WORKDIR /data
EXPOSE 8080

# /healthz touches neither the store nor the queue (liveness only). It assumes port 8080; change
# it with VOXD_ADDR and this check needs --health-cmd too.
HEALTHCHECK --interval=15s --timeout=5s --start-period=60s --retries=3 \
    CMD ["curl", "-fsS", "--max-time", "4", "-o", "/dev/null", "http://127.0.0.1:8080/healthz"]

ENTRYPOINT ["/usr/bin/tini", "--", "voxd"]
CMD ["serve"]
