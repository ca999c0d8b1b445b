# shellcheck shell=bash
# The local base images of docker/smoke.sh (sourced by it): what `docker build` would pull
# from a registry, made here from Debian's packages, because these machines reach no
# container registry and a container reaches no package registry.
#
#   make_build_base    Debian 12 (bookworm) by debootstrap, with cmake, g++ and the packages
#                      the runtime image is cut from. The same Debian release as the
#                      Dockerfile's rust:*-bookworm and distroless cc-debian12.
#   make_runtime_base  a distroless-like runtime cut from it: the files of base-files,
#                      netbase, tzdata, ca-certificates, libc6, libgcc-s1, libgomp1, libssl3
#                      and libstdc++6 (what gcr.io/distroless/cc-debian12 holds), a `nonroot`
#                      user 65532, and no shell, no package manager.
#   make_chef_base     the build base plus this machine's Rust toolchain (rustc, cargo and the
#                      standard library, copied from the rustup toolchain that `rustc` here
#                      runs) and cargo-chef, built on the host from crates.io. Debian's own
#                      rustc cannot stand in: bookworm has 1.63 and trixie 1.85, and the
#                      workspace needs 1.88 (rust-version, edition 2024).
#   make_crates_image  the chef base plus the workspace's crates (`cargo vendor` on the host)
#                      and a cargo configuration that replaces crates.io with them: the
#                      Dockerfile's CHEF_IMAGE.
#   make_lb_image      nginx for the Compose balancer: Debian testing's nginx (1.27.3 or later
#                      is needed for `resolve` in an upstream; bookworm has 1.22) and wget for
#                      the health check, run as a user `nginx` as in the official image.
#
# Each image is tagged REPOSITORY:KEY, KEY a hash of what makes it (the function's own text,
# its package lists, the image it starts from, the toolchain's version, Cargo.lock): an image
# whose tag exists is reused, so a second run on the same machine builds none of them. Older
# tags of the same repository are removed when a new one is made. `docker rmi` one to
# refresh it (its Debian packages are those of the day it was made).
#
# Needs: DOCKER (the client), WORK (a scratch directory), SRC (the workspace to vendor).

DEBIAN_MIRROR="${DEBIAN_MIRROR:-http://deb.debian.org/debian}"
BUILD_SUITE=bookworm
BUILD_PACKAGES=cmake,g++,make,binutils,libc6-dev,ca-certificates,tzdata,libssl3,netbase
RUNTIME_PACKAGES=(base-files netbase tzdata ca-certificates libc6 libgcc-s1 libgomp1 libssl3 libstdc++6)
LB_SUITE=testing
LB_PACKAGES=nginx,wget
CARGO_CHEF_VERSION=0.1.78
BASE_PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin

# key_of TEXT...: 12 hex digits of the hash of its arguments.
key_of() { printf '%s\n' "$@" | sha256sum | cut -c1-12; }

image_exists() { "$DOCKER" image inspect "$1" >/dev/null 2>&1; }

image_id() { "$DOCKER" image inspect -f '{{.Id}}' "$1"; }

# keep_only REPOSITORY TAG: removes the repository's other tags (older keys).
keep_only() {
  "$DOCKER" image ls --format '{{.Repository}}:{{.Tag}}' "$1" | grep -vxF "$1:$2" \
    | xargs -r "$DOCKER" rmi >/dev/null 2>&1 || true
}

# debootstrap_root DIR SUITE PACKAGES: a minimal Debian root with PACKAGES, without the
# downloaded .debs and package lists.
debootstrap_root() {
  local dir="$1" suite="$2" packages="$3"
  rm -rf "$dir"
  mkdir -p "$(dirname "$dir")"
  if ! nice -n 10 debootstrap --variant=minbase --include="$packages" "$suite" "$dir" \
    "$DEBIAN_MIRROR" >"$dir.log" 2>&1; then
    tail -20 "$dir.log" >&2
    return 1
  fi
  rm -rf "$dir"/var/cache/apt/archives/*.deb "$dir"/var/lib/apt/lists/*
}

# import_root DIR IMAGE [docker import options]: the directory as a one-layer image.
import_root() {
  local dir="$1" image="$2"
  shift 2
  tar --numeric-owner -C "$dir" -c . | "$DOCKER" import "$@" - "$image" >/dev/null
  rm -rf "$dir"
}

make_build_base() {
  local key
  key="$(key_of "$(declare -f make_build_base debootstrap_root import_root)" \
    "$BUILD_SUITE" "$BUILD_PACKAGES")"
  BUILD_BASE="qrpose-local/debian-build:$key"
  if image_exists "$BUILD_BASE"; then
    echo "build base: $BUILD_BASE (cached)"
    return
  fi
  echo "build base: debootstrap $BUILD_SUITE with $BUILD_PACKAGES ..."
  debootstrap_root "$WORK/roots/build" "$BUILD_SUITE" "$BUILD_PACKAGES"
  import_root "$WORK/roots/build" "$BUILD_BASE" --change "ENV PATH=$BASE_PATH"
  keep_only qrpose-local/debian-build "$key"
  echo "build base: $BUILD_BASE made"
}

# runtime_files SRC_ROOT PACKAGE...: the paths (relative, /usr-merged) of the packages'
# files and symbolic links in SRC_ROOT, without documentation.
runtime_files() {
  local root="$1" pkg list
  shift
  for pkg in "$@"; do
    list="$root/var/lib/dpkg/info/$pkg.list"
    [[ -f "$list" ]] || list="$root/var/lib/dpkg/info/$pkg:amd64.list"
    [[ -f "$list" ]] || { echo "runtime: package $pkg is not in the build base" >&2; return 1; }
    cat "$list"
  done | sed -E 's#^/(bin|sbin|lib|lib64)/#/usr/\1/#' \
    | grep -vE '^/(bin|sbin|lib|lib64)$|^/usr/share/(doc|man|info|lintian|bug)/' \
    | sort -u | while IFS= read -r path; do
      if [[ -L "$root$path" || -f "$root$path" ]]; then printf '%s\n' "${path#/}"; fi
    done
}

make_runtime_base() {
  local key src out cid
  key="$(key_of "$(declare -f make_runtime_base runtime_files import_root)" \
    "$(image_id "$BUILD_BASE")" "${RUNTIME_PACKAGES[@]}")"
  RUNTIME_BASE="qrpose-local/distroless-cc:$key"
  if image_exists "$RUNTIME_BASE"; then
    echo "runtime base: $RUNTIME_BASE (cached)"
    return
  fi
  src="$WORK/roots/runtime-src"
  out="$WORK/roots/runtime"
  rm -rf "$src" "$out"
  mkdir -p "$src" "$out"
  cid="$("$DOCKER" create "$BUILD_BASE" /bin/true)"
  "$DOCKER" export "$cid" | tar -C "$src" -x
  "$DOCKER" rm "$cid" >/dev/null
  runtime_files "$src" "${RUNTIME_PACKAGES[@]}" >"$WORK/roots/runtime.files"
  tar -C "$src" --no-recursion -c -T "$WORK/roots/runtime.files" | tar -C "$out" -x
  # /usr-merged as Debian 12 is; the loader's cache and the CA bundle that the packages'
  # scripts generated in the build base.
  for dir in bin sbin lib lib64; do ln -s "usr/$dir" "$out/$dir"; done
  cp -a "$src/etc/ld.so.cache" "$out/etc/"
  mkdir -p "$out/etc/ssl/certs"
  cp -a "$src/etc/ssl/certs/ca-certificates.crt" "$out/etc/ssl/certs/"
  # distroless's users: root, nobody and nonroot (65532), with no login shell.
  printf '%s\n' 'root:x:0:0:root:/root:/sbin/nologin' \
    'nobody:x:65534:65534:nobody:/nonexistent:/sbin/nologin' \
    'nonroot:x:65532:65532:nonroot:/home/nonroot:/sbin/nologin' >"$out/etc/passwd"
  printf '%s\n' 'root:x:0:' 'nobody:x:65534:' 'nonroot:x:65532:' >"$out/etc/group"
  printf 'hosts: files dns\n' >"$out/etc/nsswitch.conf"
  mkdir -p "$out/tmp" "$out/root" "$out/home/nonroot"
  chmod 1777 "$out/tmp"
  chmod 700 "$out/root" "$out/home/nonroot"
  chown 65532:65532 "$out/home/nonroot"
  rm -rf "$src"
  import_root "$out" "$RUNTIME_BASE" --change 'USER 65532:65532' \
    --change 'WORKDIR /home/nonroot' --change "ENV PATH=$BASE_PATH" \
    --change 'ENV SSL_CERT_FILE=/etc/ssl/certs/ca-certificates.crt'
  keep_only qrpose-local/distroless-cc "$key"
  echo "runtime base: $RUNTIME_BASE made ($(wc -l <"$WORK/roots/runtime.files") files)"
}

# toolchain_files SYSROOT: the files of the rustc, cargo and rust-std components, from
# rustup's component manifests.
toolchain_files() {
  local sysroot="$1" triple component
  triple="$(rustc -vV | sed -n 's/^host: //p')"
  for component in rustc cargo rust-std; do
    sed -n 's/^file://p' "$sysroot/lib/rustlib/manifest-$component-$triple"
  done
}

make_chef_base() {
  local key sysroot ctx
  sysroot="$(rustc --print sysroot)"
  key="$(key_of "$(declare -f make_chef_base toolchain_files)" "$(image_id "$BUILD_BASE")" \
    "$(rustc -vV)" "$(cargo -V)" "$CARGO_CHEF_VERSION")"
  CHEF_BASE="qrpose-local/rust-chef:$key"
  if image_exists "$CHEF_BASE"; then
    echo "chef base: $CHEF_BASE (cached)"
    return
  fi
  ctx="$WORK/ctx/chef"
  rm -rf "$ctx"
  mkdir -p "$ctx/rust"
  echo "chef base: $(rustc -V) from $sysroot; cargo-chef $CARGO_CHEF_VERSION built on the host ..."
  toolchain_files "$sysroot" | tar -C "$sysroot" -c -T - | tar -C "$ctx/rust" -x
  nice -n 10 cargo install --quiet --locked cargo-chef --version "$CARGO_CHEF_VERSION" \
    --root "$WORK/tools" --target-dir "$WORK/tools-target"
  cp "$WORK/tools/bin/cargo-chef" "$ctx/"
  cat >"$ctx/Dockerfile" <<EOF
FROM $BUILD_BASE
COPY rust/ /usr/local/
COPY cargo-chef /usr/local/cargo/bin/cargo-chef
ENV CARGO_HOME=/usr/local/cargo PATH=/usr/local/cargo/bin:$BASE_PATH
WORKDIR /src
EOF
  "$DOCKER" build -q -t "$CHEF_BASE" "$ctx" >/dev/null
  rm -rf "$ctx"
  keep_only qrpose-local/rust-chef "$key"
  echo "chef base: $CHEF_BASE made"
}

make_crates_image() {
  local key ctx
  key="$(key_of "$(declare -f make_crates_image)" "$(image_id "$CHEF_BASE")" \
    "$(sha256sum <"$SRC/Cargo.lock")")"
  CRATES_IMAGE="qrpose-local/chef-crates:$key"
  if image_exists "$CRATES_IMAGE"; then
    echo "crates: $CRATES_IMAGE (cached)"
    return
  fi
  ctx="$WORK/ctx/crates"
  rm -rf "$ctx"
  mkdir -p "$ctx"
  echo "crates: cargo vendor of $SRC/Cargo.lock ..."
  (cd "$SRC" && cargo vendor --quiet --locked --versioned-dirs "$ctx/vendor" >/dev/null)
  # Every crate from the vendored copy, and cargo told never to reach the network.
  cat >"$ctx/config.toml" <<'EOF'
[source.crates-io]
replace-with = "vendored-sources"

[source.vendored-sources]
directory = "/usr/local/cargo/vendor"

[net]
offline = true
EOF
  cat >"$ctx/Dockerfile" <<EOF
FROM $CHEF_BASE
COPY vendor/ /usr/local/cargo/vendor/
COPY config.toml /usr/local/cargo/config.toml
EOF
  "$DOCKER" build -q -t "$CRATES_IMAGE" "$ctx" >/dev/null
  echo "crates: $CRATES_IMAGE made ($(find "$ctx/vendor" -mindepth 1 -maxdepth 1 | wc -l) crates)"
  rm -rf "$ctx"
  keep_only qrpose-local/chef-crates "$key"
}

make_lb_image() {
  local key root
  key="$(key_of "$(declare -f make_lb_image debootstrap_root import_root)" \
    "$LB_SUITE" "$LB_PACKAGES")"
  LB_IMAGE="qrpose-local/nginx:$key"
  if image_exists "$LB_IMAGE"; then
    echo "balancer: $LB_IMAGE (cached)"
    return
  fi
  root="$WORK/roots/lb"
  echo "balancer: debootstrap $LB_SUITE with $LB_PACKAGES ..."
  debootstrap_root "$root" "$LB_SUITE" "$LB_PACKAGES"
  # The official image's worker user; its temporary files (request bodies over
  # client_body_buffer_size) go under /var/lib/nginx here.
  echo 'nginx:x:101:101:nginx:/nonexistent:/usr/sbin/nologin' >>"$root/etc/passwd"
  echo 'nginx:x:101:' >>"$root/etc/group"
  chown -R 101:101 "$root/var/lib/nginx"
  import_root "$root" "$LB_IMAGE" --change "ENV PATH=$BASE_PATH" \
    --change 'CMD ["nginx", "-g", "daemon off;"]'
  keep_only qrpose-local/nginx "$key"
  echo "balancer: $LB_IMAGE made ($(docker_nginx_version))"
}

docker_nginx_version() { "$DOCKER" run --rm "$LB_IMAGE" nginx -v 2>&1; }
