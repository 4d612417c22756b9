# autosar — developer entry points. `make test` and `make demo` set everything up from scratch.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp

.PHONY: setup test test-long demo bench bench-paper benchmarks-md modules-md figures lint clean sample-logs mutate

setup: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

test: setup
	$(BIN)/python -m pytest -q -n 2 --dist loadfile

# The checks too long for CI: the urban drive's reflectors along its 6-DOF phase centres (~10 min), test2's
# scale sweep on the truth's reflectors (compare's sar-min+scale, ~3 min), and the autofocus's scale on a class C
# road (~1 min).
test-long: setup
	$(BIN)/python -m pytest -q -s -m long

demo: setup
	$(BIN)/autosar info sample_logs/ci_seed1.mcap
	$(BIN)/autosar ingest sample_logs/ci_seed1.mcap --output demo_out/drive.h5 --overwrite
	$(BIN)/autosar info demo_out/drive.h5
	$(BIN)/autosar navigate demo_out/drive.h5 --output demo_out/trajectory.h5 --plot --overwrite
	$(BIN)/autosar focus demo_out/drive.h5 --trajectory demo_out/trajectory.h5 --output demo_out/image --overwrite
	$(BIN)/autosar run sample_logs/ci_seed1.mcap -o demo_out/run --overwrite
	$(BIN)/autosar evaluate demo_out/run -o demo_out/run/report --overwrite
	$(BIN)/autosar compare sample_logs/ci_seed1.mcap -o demo_out/compare --overwrite
	@echo "demo: drive.h5, trajectory.h5 (+ .png) and image.tif / image.h5 / image.png in demo_out/"
	@echo "demo: autosar run -> demo_out/run/ (run.json + products), its evaluation in demo_out/run/report/ (report.md, *.png)"
	@echo "demo: comparison none / ins / sar-min / truth -> demo_out/compare/compare.md, compare.png, across_track.png, compare_chips.png"

bench: setup
	$(BIN)/python benches/bench_simulate.py
	$(BIN)/python benches/bench_ingest.py
	$(BIN)/python benches/bench_navigate.py
	$(BIN)/python benches/bench_focus.py
	$(BIN)/python benches/bench_run.py

# The paper's comparison (issue 6's figures) on test1-3, seeds 0-9, on the planar motion SAR-MIN models (the
# simulator's kinematic car; the config's default is the full vehicle): ~50 min (1.7 min per drive: paper.json's rows, simulate + compare).
bench-paper: setup
	$(BIN)/python benches/bench_paper.py --dynamics kinematic

# The 40 drives of the full vehicle model (test1-3 and urban, seeds 0-9), SAR-MIN and the product's `sar-min+af`,
# measured again at the code as it is into the product's file: ~2 h on 2 cores in one process; two halves at once
# (--scenarios urban and --scenarios test1,test2,test3 to two --output files) ~75 min (the file's rows: 62 / 76 min).
PAPER_FULL := --scenarios test1,test2,test3,urban --seeds 0-9 --dynamics full --methods sar-min,sar-min+af
bench-paper-full: setup
	$(BIN)/python benches/bench_paper.py $(PAPER_FULL) --output benches/results/paper_full_slow.json

# What each effect of the full vehicle model does to the chain: test2 and urban, seed 0, one effect at a time: ~45 min (paper_ablation.json's rows).
ABLATION := slip body road tyre_radius wheel_ticks slip,body,road,tyre_radius,wheel_ticks,imu_misalignment
bench-ablation: setup
	for c in $(ABLATION); do $(BIN)/python benches/bench_paper.py --scenarios test2,urban --seeds 0 \
	  --methods sar-min,truth --components $$c --output benches/results/paper_ablation.json --resume || exit 1; done

# docs/BENCHMARKS.md from benches/results/*.json.
benchmarks-md: setup
	$(BIN)/python benches/benchmarks_md.py

# docs/MODULES.md from the modules' docstrings.
modules-md: setup
	$(BIN)/python docs/modules_md.py

# The README's pictures (docs/figures/): test1 seed 0 simulated and compared (none, ins, sar-min, truth), ~5 min.
FIGURES_WORK := demo_out/figures
figures: setup
	$(BIN)/autosar simulate --scenario test1 --seed 0 --dynamics kinematic --output $(FIGURES_WORK)/test1.mcap --overwrite
	$(BIN)/autosar compare $(FIGURES_WORK)/test1.mcap -o $(FIGURES_WORK)/compare --overwrite
	$(BIN)/python benches/docs_figures.py $(FIGURES_WORK)/compare docs/figures

# Curated mutations (benches/mutate.py): each must make a fast test fail; 403 in ~30 min on 2 cores.
mutate: setup
	$(BIN)/python benches/mutate.py --json benches/results/mutate.json

lint: setup
	$(BIN)/ruff check autosar_cli tests benches docs

# Regenerates the committed sample logs (see sample_logs/README.md).
sample-logs: setup
	$(BIN)/autosar simulate --scenario ci --seed 1 --dynamics kinematic --format mcap --output sample_logs/ci_seed1.mcap --overwrite

clean:
	rm -rf $(VENV) demo_out .pytest_cache
