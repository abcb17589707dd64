# Build stage: compile the release binary.
FROM rust:1.95-bookworm AS build
WORKDIR /src
COPY Cargo.toml Cargo.lock ./
COPY src ./src
COPY migrations ./migrations
RUN cargo build --release --locked && strip target/release/cohortforge

# Runtime stage: the binary alone, as an unprivileged user.
FROM debian:bookworm-slim
RUN useradd --system --uid 10001 --home-dir /data cohortforge \
    && mkdir -p /data && chown cohortforge /data
COPY --from=build /src/target/release/cohortforge /usr/local/bin/cohortforge
USER cohortforge
WORKDIR /data
ENV COHORTFORGE_BIND=0.0.0.0:8080 \
    COHORTFORGE_DATABASE=/data/cohortforge.db
EXPOSE 8080
VOLUME ["/data"]
ENTRYPOINT ["/usr/local/bin/cohortforge"]
