PY ?= .venv/bin/python
PIP ?= .venv/bin/pip

.PHONY: install run test test-all lint format type maps perception bench

install:
	./scripts/setup.sh

run:
	$(PY) evaluate.py

test:
	$(PY) -m pytest -q

test-all:
	$(PY) -m pytest -q -m "expensive or not expensive"

lint:
	$(PY) -m ruff check .

format:
	$(PY) -m ruff format .

type:
	$(PY) -m mypy pimm_env pimm_agents training

maps:
	$(PY) -m pimm_env.mapping iilab

perception:
	$(PY) -m training rebuild --world iilab

bench:
	$(PY) evaluate.py bench
