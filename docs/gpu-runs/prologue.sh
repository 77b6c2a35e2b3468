# The set-up the GPU runs share (sourced by run31.sh and later, from `.gpu/`, as `. ./prologue.sh`):
# the loaders' dependencies unpacked, NVIDIA's Vulkan driver, the carried binaries on PATH, the
# card named, the mock runtime's manifest written, and VRS's config for runs that switch it on.
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
export PATH=$G:$PATH
nvidia-smi -L
printf '{"file_format_version":"1.0.0","runtime":{"name":"mock","library_path":"%s"}}\n' "$G/libmock_runtime.so" > $G/mock-runtime.json
VRS='foveation.method = "vrs"; foveation.eye_tracking = "off"'
