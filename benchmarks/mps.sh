# CUDA's multi-process service (MPS) for graphed runs sharing one GPU; source this file, then
#     start_mps >> report.txt 2>&1 || echo "no MPS"     # 0: a CUDA client ran under a new server; 3: no MPS
#     ... CUDA processes started from this shell now share the GPU through the server ...
#     stop_mps
# Without MPS the GPU takes the processes in turns: four graphed runs side by side made 3.37x more env steps
# under MPS than without it (benchmarks/RESULTS.md, "GPU: several runs on one GPU"). The pipe and
# log folders are in /tmp (the driver's folder may be a read-only mount); a CUDA process finds the server through
# CUDA_MPS_PIPE_DIRECTORY, exported here. Every step has a timeout, so a machine without MPS costs seconds.
export CUDA_MPS_PIPE_DIRECTORY=${CUDA_MPS_PIPE_DIRECTORY:-/tmp/mps_pipe}
export CUDA_MPS_LOG_DIRECTORY=${CUDA_MPS_LOG_DIRECTORY:-/tmp/mps_log}

stop_mps() { echo quit | timeout 20 nvidia-cuda-mps-control >/dev/null 2>&1; }

start_mps() {
    local py=${PYTHON:-python3}
    mkdir -p "$CUDA_MPS_PIPE_DIRECTORY" "$CUDA_MPS_LOG_DIRECTORY"
    if ! command -v nvidia-cuda-mps-control >/dev/null; then
        echo "MPS: nvidia-cuda-mps-control not found on PATH"; return 3
    fi
    if ! timeout 30 nvidia-cuda-mps-control -d; then
        echo "MPS: the control daemon did not start"; return 3
    fi
    # the server itself starts with the first CUDA context: one client before the real work
    if ! timeout 90 "$py" -c "import torch; x = torch.ones(1024, device='cuda'); print('MPS client ok', float(x @ x))"; then
        echo "MPS: a CUDA client failed under the server; stopping it"
        tail -n 20 "$CUDA_MPS_LOG_DIRECTORY"/*.log 2>/dev/null
        stop_mps; return 3
    fi
    echo "MPS: server up ($(echo get_server_list | timeout 10 nvidia-cuda-mps-control 2>&1 | tr '\n' ' '))"
}
