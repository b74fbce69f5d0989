#!/usr/bin/env bash
# lib/'s layering: core includes only core's headers; io, synth and testdata include core's and
# their own, never each other's. Reads every quoted #include in lib/<role>/ (sources and headers):
# "treestereo/x.hpp" must be a header of an allowed role, a bare "x.hpp" one of the role's own
# src/ headers, and nothing may reach out with "../". Usage: check-layering.sh [source root]
set -euo pipefail
root=${1:-$(dirname "$0")/../..}
lib=$root/lib
roles="core io synth testdata"
allowed() { # role -> roles whose headers it may include
  case $1 in
    core) echo core ;;
    *) echo "core $1" ;;
  esac
}
owner() { # header name -> the role that holds lib/<role>/include/treestereo/<name>
  local r
  for r in $roles; do
    if [ -f "$lib/$r/include/treestereo/$1" ]; then
      echo "$r"
      return
    fi
  done
}
bad=0
for role in $roles; do
  [ -d "$lib/$role" ] || { echo "missing lib/$role"; bad=1; continue; }
  while IFS= read -r file; do
    while IFS= read -r inc; do
      case $inc in
        treestereo/*)
          who=$(owner "${inc#treestereo/}")
          if [ -z "$who" ]; then
            echo "${file#"$root"/}: \"$inc\" is no header of lib/"
            bad=1
          elif ! [[ " $(allowed "$role") " == *" $who "* ]]; then
            echo "${file#"$root"/}: $role includes $who's \"$inc\""
            bad=1
          fi ;;
        */*)
          echo "${file#"$root"/}: \"$inc\" reaches outside lib/$role"
          bad=1 ;;
        *)
          if [ ! -f "$lib/$role/src/$inc" ]; then
            echo "${file#"$root"/}: \"$inc\" is not in lib/$role/src"
            bad=1
          fi ;;
      esac
    done < <(sed -n 's/^[[:space:]]*#[[:space:]]*include[[:space:]]*"\([^"]*\)".*/\1/p' "$file")
  done < <(find "$lib/$role" -type f \( -name '*.cpp' -o -name '*.hpp' \) | sort)
done
if [ "$bad" -ne 0 ]; then
  echo "lib/ layering broken (see lib/meson.build)"
  exit 1
fi
echo "lib/ layering holds: core alone; io, synth, testdata on core"
