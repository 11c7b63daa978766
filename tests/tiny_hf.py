"""Foundation models of the detect and priors stages and articulate's vision-language models,
built from tiny configurations with random weights and written as ``save_pretrained`` writes
them: the stages' loading, pre- and post-processing and output format run without a download."""

from pathlib import Path

import torch


def tiny_owlv2(d: Path) -> Path:
    from transformers import CLIPTokenizer, Owlv2Config, Owlv2ForObjectDetection, Owlv2ImageProcessor, Owlv2Processor

    vocab = {c: i for i, c in enumerate([chr(c) for c in range(ord("a"), ord("z") + 1)] + [" "])}
    vocab.update({f"{c}</w>": len(vocab) + i for i, c in enumerate(list(vocab))})
    vocab.update({"<|startoftext|>": len(vocab), "<|endoftext|>": len(vocab) + 1})
    tok = CLIPTokenizer(vocab=vocab, merges=[], model_max_length=16)
    cfg = Owlv2Config(text_config=dict(vocab_size=len(vocab), hidden_size=32, intermediate_size=64, num_hidden_layers=2,
                                       num_attention_heads=2, max_position_embeddings=16,
                                       bos_token_id=len(vocab) - 2, eos_token_id=len(vocab) - 1, pad_token_id=len(vocab) - 1),
                      vision_config=dict(hidden_size=32, intermediate_size=64, num_hidden_layers=2, num_attention_heads=2,
                                         image_size=64, patch_size=16), projection_dim=32)
    torch.manual_seed(0)
    m = Owlv2ForObjectDetection(cfg)
    with torch.no_grad():  # random box offsets make degenerate boxes: start from each patch's own box, as training does
        m.box_head.dense2.weight.mul_(0.01)
        m.box_head.dense2.bias.zero_()
    m.save_pretrained(d)
    Owlv2Processor(image_processor=Owlv2ImageProcessor(size={"height": 64, "width": 64}), tokenizer=tok).save_pretrained(d)
    return d


def tiny_sam(d: Path) -> Path:
    from transformers import (SamConfig, SamImageProcessor, SamMaskDecoderConfig, SamModel, SamProcessor,
                              SamPromptEncoderConfig, SamVisionConfig)

    vc = SamVisionConfig(hidden_size=32, num_hidden_layers=2, num_attention_heads=2, image_size=128, patch_size=16,
                         output_channels=32, mlp_dim=64, global_attn_indexes=[1], window_size=4, num_pos_feats=16)
    pc = SamPromptEncoderConfig(hidden_size=32, image_size=128, patch_size=16, mask_input_channels=4)
    mc = SamMaskDecoderConfig(hidden_size=32, num_hidden_layers=2, num_attention_heads=2, mlp_dim=64, iou_head_hidden_dim=32)
    torch.manual_seed(1)
    SamModel(SamConfig(vision_config=vc, prompt_encoder_config=pc, mask_decoder_config=mc)).save_pretrained(d)
    ip = SamImageProcessor(size={"longest_edge": 128}, pad_size={"height": 128, "width": 128},
                           mask_size={"longest_edge": 32}, mask_pad_size={"height": 32, "width": 32})
    SamProcessor(image_processor=ip).save_pretrained(d)
    return d


def tiny_depth_anything(d: Path, metric: bool = False) -> Path:
    from transformers import DepthAnythingConfig, DepthAnythingForDepthEstimation, Dinov2Config, DPTImageProcessor

    bc = Dinov2Config(hidden_size=32, num_hidden_layers=4, num_attention_heads=2, intermediate_size=64, image_size=56,
                      patch_size=14, out_features=["stage1", "stage2", "stage3", "stage4"], reshape_hidden_states=False)
    cfg = DepthAnythingConfig(backbone_config=bc, neck_hidden_sizes=[8, 16, 32, 32], fusion_hidden_size=16,
                              head_hidden_size=8, reassemble_hidden_size=32, patch_size=14,
                              depth_estimation_type="metric" if metric else "relative", max_depth=10)
    torch.manual_seed(2)
    DepthAnythingForDepthEstimation(cfg).save_pretrained(d)
    DPTImageProcessor(size={"height": 56, "width": 56}, keep_aspect_ratio=True, ensure_multiple_of=14,
                      image_mean=[0.485, 0.456, 0.406], image_std=[0.229, 0.224, 0.225]).save_pretrained(d)
    return d


def _word_tokenizer(special: list[str], roles: tuple[str, str]):
    """(word-level fast tokenizer, its vocabulary): the answer words first, so token 0 is
    "drawer"; ``special`` tokens are matched whole inside words; ``roles`` the chat roles."""
    from tokenizers import Tokenizer, decoders, models, pre_tokenizers
    from transformers import PreTrainedTokenizerFast

    words = ["drawer", "door", "panel", "<unk>", "<pad>", "<s>", "</s>", *roles, *special]
    vocab = {w: i for i, w in enumerate(words)}
    t = Tokenizer(models.WordLevel(vocab, unk_token="<unk>"))
    t.pre_tokenizer = pre_tokenizers.WhitespaceSplit()
    t.decoder = decoders.WordPiece(prefix="##")  # joins words with spaces
    tok = PreTrainedTokenizerFast(tokenizer_object=t, unk_token="<unk>", pad_token="<pad>", bos_token="<s>",
                                  eos_token="</s>", additional_special_tokens=special)
    return tok, vocab


def _chat_template(user: str, assistant: str, end: str = "") -> str:
    return ("{% for m in messages %}" + user + " {% for c in m['content'] %}{% if c['type'] == 'image' %}<image> "
            "{% else %}{{ c['text'] }} {% endif %}{% endfor %}" + end + "{% endfor %}"
            "{% if add_generation_prompt %}" + assistant + "{% endif %}")


def _llama(vocab: dict[str, int], max_positions: int) -> dict:
    return dict(model_type="llama", vocab_size=len(vocab), hidden_size=16, intermediate_size=32, num_hidden_layers=2,
                num_attention_heads=2, num_key_value_heads=2, max_position_embeddings=max_positions,
                bos_token_id=vocab["<s>"], eos_token_id=vocab["</s>"], pad_token_id=vocab["<pad>"])


def _save_answering_drawer(m, proc, d: Path) -> Path:
    """Zero ``m``'s language head (every logit 0: greedy decoding answers token 0, "drawer"),
    save it and its processor to ``d``."""
    with torch.no_grad():
        m.lm_head.weight.zero_()
    m.save_pretrained(d)
    proc.save_pretrained(d)
    return d


def tiny_llava(d: Path) -> Path:
    """A LLaVA (CLIP vision tower, Llama text model) with a word-level tokenizer and a chat
    template, answering "drawer" to everything: a reply whose parse is known."""
    from transformers import CLIPImageProcessor, CLIPVisionConfig, LlavaConfig, LlavaForConditionalGeneration, LlavaProcessor

    tok, vocab = _word_tokenizer(["<image>"], ("USER:", "ASSISTANT:"))
    ip = CLIPImageProcessor(size={"shortest_edge": 32}, crop_size={"height": 32, "width": 32})
    proc = LlavaProcessor(image_processor=ip, tokenizer=tok, patch_size=8, vision_feature_select_strategy="default",
                          chat_template=_chat_template("USER:", "ASSISTANT:"), num_additional_image_tokens=1)
    cfg = LlavaConfig(vision_config=CLIPVisionConfig(hidden_size=16, intermediate_size=32, num_hidden_layers=2,
                                                     num_attention_heads=2, image_size=32, patch_size=8),
                      text_config=_llama(vocab, 64), image_token_index=vocab["<image>"], image_seq_length=16,
                      vision_feature_layer=-1)
    torch.manual_seed(3)
    return _save_answering_drawer(LlavaForConditionalGeneration(cfg), proc, d)


def tiny_idefics3(d: Path) -> Path:
    """An Idefics3 (SmolVLM's architecture: SigLIP-style vision tower, pixel shuffle, Llama text
    model) whose processor splits an image into tiles with row / column tokens, as SmolVLM's
    does; it answers "drawer" to everything."""
    from transformers import Idefics3Config, Idefics3ForConditionalGeneration, Idefics3ImageProcessor, Idefics3Processor

    special = ["<fake_token_around_image>", "<image>", "<end_of_utterance>", "<global-img>"] + \
        [f"<row_{i}_col_{j}>" for i in range(1, 7) for j in range(1, 7)]
    tok, vocab = _word_tokenizer(special, ("User:", "Assistant:"))
    ip = Idefics3ImageProcessor(size={"longest_edge": 64}, max_image_size={"longest_edge": 32}, do_image_splitting=True)
    proc = Idefics3Processor(image_processor=ip, tokenizer=tok, image_seq_len=4,
                             chat_template=_chat_template("User:", "Assistant:", "<end_of_utterance> "))
    cfg = Idefics3Config(vision_config=dict(hidden_size=16, intermediate_size=32, num_hidden_layers=2, num_attention_heads=2,
                                            image_size=32, patch_size=8),
                         text_config=_llama(vocab, 512), image_token_id=vocab["<image>"], scale_factor=2,
                         pad_token_id=vocab["<pad>"])
    torch.manual_seed(4)
    return _save_answering_drawer(Idefics3ForConditionalGeneration(cfg), proc, d)
