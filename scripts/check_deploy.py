#!/usr/bin/env python3
"""Checks the deployment files statically, without a Docker engine or a cluster
(docker/smoke.sh builds and runs them for real; docs/deploy.md).

Parses docker/compose.yaml and docker/k8s/*.yaml and checks that they name what the
deployment relies on: the services and their health checks, the environment-only
configuration, resource limits, the load balancer and its config, the probes, the non-root
security context, the Service and the autoscaler; that docker/compose.secure.yaml and the
Kubernetes Deployment take the auth file and the TLS files from mounted secrets, and that
the probes speak HTTPS when TLS is on (docs/security.md); and that the Dockerfile keeps the
properties hadolint does not know about (non-root user, port, health check, entrypoint, no
`# syntax=` line); and that nginx passes WebSocket upgrades on /v1/stream.

Usage: python3 scripts/check_deploy.py   (needs PyYAML). Exit 0 when every check holds, 1
otherwise, with one line per failed check.
"""

import re
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parent.parent
DOCKER = ROOT / "docker"
PORT = 8080
HEALTHCHECK = ["CMD", "/usr/local/bin/qrpose", "healthcheck"]

failures = []


def check(condition, message):
    if not condition:
        failures.append(message)
    return condition


def default_of(value):
    """A Compose value with its `${NAME:-default}` variables replaced by their defaults."""
    return re.sub(r"\$\{[A-Z0-9_]+:-([^}]*)\}", r"\1", str(value))


def load_all(path):
    with path.open(encoding="utf-8") as f:
        return [doc for doc in yaml.safe_load_all(f) if doc is not None]


def check_dockerfile():
    text = (DOCKER / "Dockerfile").read_text(encoding="utf-8")
    stages = re.findall(r"^FROM\s+(\S+)(?:\s+AS\s+(\S+))?", text, re.M | re.I)
    check(len(stages) >= 2, "Dockerfile: not a multi-stage build")
    check(not re.search(r"^#\s*syntax\s*=", text, re.M | re.I),
          "Dockerfile: no `# syntax=` line (BuildKit would fetch a frontend image; docker/smoke.sh "
          "builds with none reachable)")
    check("--locked" in text and "--features zxing-cpp" in text,
          "Dockerfile: the release build must use --locked and --features zxing-cpp")
    check("cargo chef cook" in text, "Dockerfile: no separate dependency layer (cargo chef cook)")
    users = re.findall(r"^USER\s+(\S+)", text, re.M)
    check(users and users[-1].split(":")[0] not in ("0", "root"),
          "Dockerfile: the runtime stage must run as a non-root user")
    check(re.search(r"^ENV\s+QRPOSE_ADDR=0\.0\.0\.0:8080\b", text, re.M),
          "Dockerfile: ENV QRPOSE_ADDR=0.0.0.0:8080 missing")
    check(re.search(rf"^EXPOSE\s+{PORT}\b", text, re.M), f"Dockerfile: EXPOSE {PORT} missing")
    check(re.search(r'^HEALTHCHECK\b.*\n?.*CMD \["/usr/local/bin/qrpose", "healthcheck"\]',
                    text, re.M),
          "Dockerfile: HEALTHCHECK must run `qrpose healthcheck`")
    check(re.search(r"^STOPSIGNAL\s+SIGTERM\b", text, re.M), "Dockerfile: STOPSIGNAL SIGTERM missing")
    check(re.search(r'^ENTRYPOINT \["/usr/local/bin/qrpose"\]', text, re.M),
          "Dockerfile: exec-form ENTRYPOINT (the binary as PID 1, receiving SIGTERM) missing")
    ignore = (ROOT / ".dockerignore").read_text(encoding="utf-8").split()
    check("/target" in ignore and "/.git" in ignore, ".dockerignore: target/ and .git must be ignored")


def check_compose():
    (compose,) = load_all(DOCKER / "compose.yaml")
    services = compose.get("services", {})
    for name in ("qrpose", "replica", "lb"):
        check(name in services, f"compose: service `{name}` missing")
    for name in ("qrpose", "replica"):
        service = services.get(name, {})
        check(service.get("healthcheck", {}).get("test") == HEALTHCHECK,
              f"compose: `{name}` healthcheck must be {HEALTHCHECK}")
        env = service.get("environment", {})
        check(isinstance(env, dict) and env.get("QRPOSE_ADDR") == f"0.0.0.0:{PORT}",
              f"compose: `{name}` must be configured by environment (QRPOSE_ADDR)")
        check(all(k.startswith(("QRPOSE_", "RUST_LOG")) for k in env),
              f"compose: `{name}` has environment variables qrpose does not read")
        limits = service.get("deploy", {}).get("resources", {}).get("limits", {})
        check("cpus" in limits and "memory" in limits, f"compose: `{name}` needs CPU and memory limits")
        check(service.get("build", {}).get("dockerfile") == "docker/Dockerfile",
              f"compose: `{name}` must build docker/Dockerfile")
    check(any(default_of(p).endswith(f":{PORT}") for p in services.get("qrpose", {}).get("ports", [])),
          f"compose: `qrpose` must publish port {PORT}")
    check(services.get("replica", {}).get("deploy", {}).get("replicas", 0) >= 2,
          "compose: `replica` needs two or more replicas")
    check("ports" not in services.get("replica", {}), "compose: replicas must not publish ports")
    lb = services.get("lb", {})
    lb_image = default_of(lb.get("image", ""))
    check(lb_image.startswith(("nginx:", "traefik:")) and not lb_image.endswith(":latest"),
        "compose: `lb` must be an official nginx or Traefik image pinned by tag")
    check("replica" in lb.get("depends_on", {}), "compose: `lb` must depend on `replica`")
    mounts = [v.split(":")[0] for v in lb.get("volumes", [])]
    check("./nginx.conf" in mounts, "compose: `lb` must mount ./nginx.conf")
    nginx = (DOCKER / "nginx.conf").read_text(encoding="utf-8")
    check(re.search(rf"server\s+replica:{PORT}\b", nginx), "nginx.conf: upstream `replica` missing")
    check(re.search(r"client_max_body_size\s+24m;", nginx),
          "nginx.conf: client_max_body_size must let a 24 MiB photo through")
    check(re.search(r"proxy_pass\s+http://qrpose;", nginx), "nginx.conf: proxy_pass to the upstream missing")
    stream = re.search(r"location\s*=\s*/v1/stream\s*\{([^}]*)\}", nginx)
    body = stream.group(1) if stream else ""
    check(stream and re.search(r"proxy_set_header\s+Upgrade\s+\$http_upgrade;", body)
          and re.search(r"proxy_set_header\s+Connection\s+\$connection_upgrade;", body)
          and re.search(r"proxy_http_version\s+1\.1;", body)
          and re.search(r"proxy_read_timeout\s+\d+[hm];", body),
          "nginx.conf: /v1/stream must pass WebSocket upgrades (HTTP/1.1, Upgrade and Connection "
          "headers, a read timeout in minutes or hours)")


def check_compose_secure():
    """docker/compose.secure.yaml: the auth file and the TLS files as Compose secrets, each
    variable pointing at its secret's file under /run/secrets/."""
    (override,) = load_all(DOCKER / "compose.secure.yaml")
    service = override.get("services", {}).get("qrpose", {})
    env = service.get("environment", {})
    declared = override.get("secrets", {})
    mounted = [s if isinstance(s, str) else s.get("source") for s in service.get("secrets", [])]
    for variable in ("QRPOSE_AUTH_FILE", "QRPOSE_TLS_CERT", "QRPOSE_TLS_KEY"):
        path = str(env.get(variable, ""))
        name = path.removeprefix("/run/secrets/")
        check(path.startswith("/run/secrets/") and name in mounted and "file" in declared.get(name, {}),
              f"compose.secure: {variable} must point at a secret of `qrpose` (/run/secrets/NAME)")
    files = [str(v.get("file", "")) for v in declared.values()]
    check(all(f.startswith("./secrets/") for f in files),
          "compose.secure: secret files belong in docker/secrets/ (ignored by git)")
    gitignore = (ROOT / ".gitignore").read_text(encoding="utf-8").split()
    check("/docker/secrets/" in gitignore, ".gitignore: /docker/secrets/ must be ignored")


def probe(container, kind):
    return container.get(kind, {}).get("httpGet", {})


def check_kubernetes():
    docs = []
    for path in sorted((DOCKER / "k8s").glob("*.yaml")):
        docs.extend(load_all(path))
    by_kind = {doc.get("kind"): doc for doc in docs}
    for kind in ("Deployment", "Service", "HorizontalPodAutoscaler"):
        check(kind in by_kind, f"k8s: no {kind}")
    deployment = by_kind.get("Deployment", {})
    template = deployment.get("spec", {}).get("template", {})
    labels = template.get("metadata", {}).get("labels", {})
    selector = deployment.get("spec", {}).get("selector", {}).get("matchLabels", {})
    check(selector and selector.items() <= labels.items(),
          "k8s: the Deployment's selector must match its pod labels")
    pod = template.get("spec", {})
    containers = pod.get("containers", [])
    check(len(containers) == 1, "k8s: one container expected")
    container = containers[0] if containers else {}
    env = {e.get("name"): e.get("value") for e in container.get("env", [])}
    tls = "QRPOSE_TLS_CERT" in env
    port_name = "https" if tls else "http"
    ports = {p.get("name"): p.get("containerPort") for p in container.get("ports", [])}
    check(ports.get(port_name) == PORT, f"k8s: container port `{port_name}` must be {PORT}")
    check(env.get("QRPOSE_ADDR") == f"0.0.0.0:{PORT}", "k8s: QRPOSE_ADDR must listen on 0.0.0.0")
    check(probe(container, "readinessProbe").get("path") == "/readyz",
          "k8s: readiness probe must GET /readyz")
    check(probe(container, "livenessProbe").get("path") == "/healthz",
          "k8s: liveness probe must GET /healthz")
    for kind in ("readinessProbe", "livenessProbe"):
        check(probe(container, kind).get("port") in (port_name, PORT), f"k8s: {kind} on the wrong port")
        check(probe(container, kind).get("scheme", "HTTP") == ("HTTPS" if tls else "HTTP"),
              f"k8s: {kind} must use {'HTTPS' if tls else 'HTTP'}")
    # Tokens and TLS from Secrets mounted as whole directories (docs/security.md).
    secret_dirs = {}
    volumes = {v.get("name"): v for v in pod.get("volumes", [])}
    for mount in container.get("volumeMounts", []):
        volume = volumes.get(mount.get("name"), {})
        if "secret" in volume:
            check(mount.get("readOnly") is True and "subPath" not in mount,
                  f"k8s: the Secret mount {mount.get('name')} must be read-only and whole (no subPath)")
            secret_dirs[mount.get("mountPath", "").rstrip("/")] = volume["secret"].get("secretName")
    for variable in ("QRPOSE_AUTH_FILE", "QRPOSE_TLS_CERT", "QRPOSE_TLS_KEY"):
        directory = str(env.get(variable, "")).rsplit("/", 1)[0]
        check(directory in secret_dirs, f"k8s: {variable} must be a file of a mounted Secret")
    resources = container.get("resources", {})
    for bound in ("requests", "limits"):
        check({"cpu", "memory"} <= set(resources.get(bound, {})),
              f"k8s: resource {bound} need cpu and memory")
    pod_security = pod.get("securityContext", {})
    container_security = container.get("securityContext", {})
    check(pod_security.get("runAsNonRoot") is True and pod_security.get("runAsUser", 0) != 0,
          "k8s: the pod must run as a non-root user")
    check(container_security.get("allowPrivilegeEscalation") is False,
          "k8s: allowPrivilegeEscalation must be false")
    check(container_security.get("readOnlyRootFilesystem") is True,
          "k8s: the root filesystem must be read-only")
    check("ALL" in container_security.get("capabilities", {}).get("drop", []),
          "k8s: capabilities must drop ALL")
    grace_ms = int(env.get("QRPOSE_SHUTDOWN_GRACE_MS", "10000"))
    pre_stop_s = container.get("lifecycle", {}).get("preStop", {}).get("sleep", {}).get("seconds", 0)
    check(pre_stop_s * 1000 + grace_ms < pod.get("terminationGracePeriodSeconds", 30) * 1000,
          "k8s: preStop sleep + QRPOSE_SHUTDOWN_GRACE_MS must fit terminationGracePeriodSeconds")
    service = by_kind.get("Service", {})
    check(service.get("spec", {}).get("selector", {}).items() <= labels.items()
          and service.get("spec", {}).get("selector"),
          "k8s: the Service's selector must match the pods")
    check(any(p.get("targetPort") in (port_name, PORT) for p in service.get("spec", {}).get("ports", [])),
          "k8s: the Service must target the container port")
    hpa = by_kind.get("HorizontalPodAutoscaler", {})
    target = hpa.get("spec", {}).get("scaleTargetRef", {})
    check(target.get("kind") == "Deployment"
          and target.get("name") == deployment.get("metadata", {}).get("name"),
          "k8s: the autoscaler must scale the Deployment")
    metrics = hpa.get("spec", {}).get("metrics", [])
    check(any(m.get("resource", {}).get("name") == "cpu" for m in metrics),
          "k8s: the autoscaler must scale on CPU")
    check(hpa.get("apiVersion") == "autoscaling/v2", "k8s: use autoscaling/v2")


def main():
    for step in (check_dockerfile, check_compose, check_compose_secure, check_kubernetes):
        try:
            step()
        except (OSError, yaml.YAMLError, ValueError, AttributeError, TypeError) as e:
            failures.append(f"{step.__name__}: {e}")
    for failure in failures:
        print(f"FAIL: {failure}")
    if failures:
        return 1
    print("deployment files: ok (Dockerfile, compose.yaml, compose.secure.yaml, nginx.conf, k8s/)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
