"""Regenerate ``repro/data_registry.csv`` from the staged data's own provenance files.

Run once when the staged data changes:
    python scripts/make_data_registry.py ../shared/data > repro/data_registry.csv

Every row: dataset, the file's path relative to the data folder *uncompressed*
(a staged ``.gz`` beside it counts as the same file), the sha256 of the
uncompressed content (what the public URL serves), and that public URL (empty
when the file has no public original, e.g. the CMU BVH files, which were
converted from the public ASF/AMC).
"""

import csv
import re
import sys
from pathlib import Path

root = Path(sys.argv[1])
out = csv.writer(sys.stdout, lineterminator="\n")
out.writerow(["dataset", "path", "sha256", "url"])

# ICT Face Model: the PROVENANCE table gives path, raw URL and upstream sha256.
for line in (root / "faces/ict/PROVENANCE.md").read_text().splitlines():
    m = re.match(r"\| `([^`]+)` \| `[^`]+` \| (https://\S+) \| \d+ \| `([0-9a-f]{64})` \|", line)
    if m:
        staged, url, sha = m.groups()
        out.writerow(["ict", "faces/ict/" + staged.removesuffix(".gz"), sha, url])

# CMU ASF/AMC originals: SHA256SUMS (uncompressed) + URL pattern of PROVENANCE.md.
enc = "https://raw.githubusercontent.com/encadyma/motion-out/4855c55bcba49e94b683969dbd6d1e2de8ecffb8/assets"
usc = "https://raw.githubusercontent.com/BrandoZhang/Motion_Capture_Interpolation/cd6da1c772b3947a034aaf649f5d89c5aa953699/mocapPlayer-starter"
special = {
    "135.asf": f"{enc}/asf/martialwalk.asf",
    "131.asf": f"{enc}/asf/mjackson.asf",
    "07.asf": f"{usc}/07-walk.asf",
    "09.asf": f"{usc}/09-run.asf",
    "07_05.amc": f"{usc}/07_05-walk.amc",
    "09_06.amc": f"{usc}/09_06-run.amc",
}
for line in (root / "mocap/cmu/source/SHA256SUMS").read_text().splitlines():
    sha, name = line.split()
    if name in special:
        url = special[name]
    elif name.startswith("135_"):
        url = f"{enc}/amc/martialwalk/{name}"
    elif name.startswith("131_"):
        url = f"{enc}/amc/mjackson/{name}"
    else:
        raise SystemExit(f"no URL rule for {name}")
    out.writerow(["cmu-asfamc", f"mocap/cmu/source/{name}", sha, url])

# CMU BVH (converted; no public original) and Bandai Namco BVH: their manifests.
for dataset, folder in [("cmu-bvh", "mocap/cmu"), ("bandai", "mocap/bandai")]:
    with open(root / folder / "manifest.csv", newline="") as fh:
        for row in csv.DictReader(fh):
            url = row["source_path"] if dataset == "bandai" else ""
            out.writerow([dataset, f"{folder}/{row['file']}", row["sha256"], url])
