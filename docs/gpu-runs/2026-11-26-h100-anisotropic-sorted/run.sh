#!/bin/bash
# The same run as ../2026-11-26-h100-anisotropic/run.sh at commit 92d7094
# (the kernel and guess passes in the grid's cell order).
exec "$(dirname "$0")/../2026-11-26-h100-anisotropic/run.sh"
